"""task=map (the default): stream frames, classify touches, train the field online, score it.

    python run.py sensor=sim object=plushie
    python run.py object=patched_toy mapping.resume=outputs/map/.../checkpoint.pt

Writes the run-output contract of docs/design.md into the run directory: metrics.json,
material_mesh.ply, matching_curve.png, material_maps.png, uncertainty_map.png, progression.png,
checkpoint.pt (every mapping.checkpoint_every frames and at the end) and touches.csv.
A resumed run continues in its checkpoint's directory and its metrics.json covers every
segment. SIGINT / SIGTERM: the outputs are written, marked partial, and the process exits
130 / 143 with one line on stderr (tasks/runner.py). The directory, lock and resume
checks run before any of this (tasks/run_guard.py). The frame loop is pipeline/mapping_session.py; this module only wires the config to it.
"""

from __future__ import annotations

import logging
import signal
from collections.abc import Sequence
from pathlib import Path

from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.configs import to_config
from neuralfeels_sem.core.errors import FrameSourceError, UserError
from neuralfeels_sem.eval.oracles import oracles_used
from neuralfeels_sem.mapping.pose_source import build_pose_source
from neuralfeels_sem.mapping.pose_tracker import TrackerConfig
from neuralfeels_sem.pipeline.interrupts import Interrupted
from neuralfeels_sem.pipeline.mapping_session import MappingSession
from neuralfeels_sem.pipeline.run_outputs import (
    load_avg,
    machine_info,
    write_metrics,
    write_touches,
)
from neuralfeels_sem.pipeline.session_settings import SessionSettings, helper_nice_at
from neuralfeels_sem.pipeline.touch_advisor import TouchAdvisorConfig, touch_advisors
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.build import (
    BOUND_MARGIN,
    build_mapper,
    build_scorer,
    model_config,
)
from neuralfeels_sem.tasks.run_guard import run_provenance
from neuralfeels_sem.tasks.runner import output_dir
from neuralfeels_sem.utils.code_version import code_version
from neuralfeels_sem.utils.device import resolve_device
from neuralfeels_sem.viz.live import build_live_view
from neuralfeels_sem.viz.run_report import print_summary, write_pictures
from neuralfeels_sem.viz.segmentation_overlay import write_segmentation_pictures

log = logging.getLogger(__name__)


def run(cfg: DictConfig) -> dict:
    code_version()  # the code this process started with, before a long run (cached)
    class_names = list(cfg.materials)
    obj = instantiate(cfg.object)
    own_process = bool(cfg.mapping.acquire_process)
    nice = helper_nice_at(int(cfg.mapping.helper_nice), cfg.sensor.get("pace", "offline"))
    sensor = build_sensor(cfg.sensor, obj, class_names, own_process, nice)
    sensor.open()  # a missing device ends the run here, before any heavy work
    try:
        out = output_dir()
        advisors = touch_advisors(to_config(TouchAdvisorConfig, cfg.mapping.advisor), sensor, out)
        live = build_live_view(
            cfg.viz.live,
            out,
            class_names,
            spawn=cfg.viz.live_spawn,
            mesh_resolution=cfg.viz.live_mesh_resolution,
            camera_points=cfg.viz.live_camera_points,
        )
        return map_object(cfg, obj, sensor, out, observers=[*advisors, *live])
    finally:
        sensor.close()


def map_object(cfg: DictConfig, obj, sensor, out: Path, observers: Sequence = ()) -> dict:
    """Map an opened sensor's frames; writes every run output into `out`.

    `observers` (pipeline/observers.py) are told of every frame and scoring pass."""
    device = resolve_device(cfg.device)
    session = build_session(cfg, obj, sensor, out, device, observers)
    if (caveat := tracked_realtime_caveat(cfg.mapping.pose, sensor.pace, device)) is not None:
        log.warning(caveat)
    metrics = run_metrics(cfg, obj, sensor, session, device)
    if caveat is not None:
        metrics["notes"].append(caveat)
    write_metrics(metrics, out / "metrics.json")
    write_touches(
        session.scorer.touch_log,
        list(cfg.materials),
        out / "touches.csv",
        partial=metrics["partial"],
    )
    if cfg.viz.plots:
        dpi = int(cfg.viz.dpi)
        write_pictures(session.scorer.class_names, metrics, session.snapshots_dir, out, dpi)
        session.pose_source.write_pictures(out, dpi)
        write_segmentation_pictures(session.mapper.points, out)
    print_summary(metrics, out)
    if session.failure is not None:
        raise _failed(session.failure, metrics, out)
    if metrics["partial"]:
        raise _interrupted(metrics, out)
    return metrics


def tracked_realtime_caveat(pose: str, pace: str, device) -> str | None:
    """The warning a tracked pose at realtime pace on a CPU gets: measured on the 2-core
    CPU the tracker lost the object in every run (docs/pose.md, known limitations)."""
    if pose == "gt" or pace != "realtime" or device.type != "cpu":
        return None
    return (
        f"mapping.pose={pose} at sensor.pace=realtime on a CPU: on the 2-core CPU the tracker "
        "lost the object in every measured run (pose error 18-70 mm, maps near the majority "
        "map); map with sensor.pace=offline, or give the rig markers (mapping.pose=gt)"
    )


def build_session(
    cfg: DictConfig, obj, sensor, out: Path, device, observers: Sequence
) -> MappingSession:
    """The mapper, classifier, scorer and pose source of a run, in one session."""
    # Built in this order (classifier first) so the field's random initialisation, and with
    # it every figure, is the one earlier runs of the same seed had.
    classifier = instantiate(cfg.classifier)
    bound = BOUND_MARGIN * obj.bounds_radius
    mapper = build_mapper(cfg, bound, device, sensor.hand_model())
    scorer = build_scorer(cfg, obj)
    # A PoseTracker is built only when mapping.pose tracks.
    tracker = to_config(TrackerConfig, cfg.mapping.tracker)
    settings = SessionSettings(
        every_k_frames=int(cfg.eval.every_k_frames),
        checkpoint_every=int(cfg.mapping.checkpoint_every),
        progression_snapshots=int(cfg.viz.progression_snapshots),
        max_lag_s=float(cfg.mapping.max_lag_s),
        checkpoint_storage=str(cfg.mapping.checkpoint_storage),
        acquire_thread=bool(cfg.mapping.acquire_thread),
        helper_nice=int(cfg.mapping.helper_nice),
        overtaken_touch_frames=int(cfg.mapping.overtaken_touch_frames),
    )
    return MappingSession(
        mapper,
        classifier,
        scorer,
        build_pose_source(cfg.mapping.pose, obj, tracker),
        out,
        bound,
        model_config(cfg),
        settings,
        provenance=run_provenance(cfg, obj),
        observers=observers,
    )


def run_metrics(cfg: DictConfig, obj, sensor, session: MappingSession, device) -> dict:
    """Run the session and gather metrics.json: scores, timing, provenance of the figures."""
    scores = session.run(sensor, resume=cfg.mapping.resume)
    mapper, pose_source = session.mapper, session.pose_source
    return {
        **scores,
        # what the run's figures rest on: the scorer's notes, then frames not tracked
        "notes": [*scores.get("notes", []), *pose_source.notes()],
        "machine": machine_info(device),
        "code": code_version(),  # the commit the figures come from
        "load_avg": load_avg(),  # 1, 5, 15 min at the end
        "trained_on": mapper.trained_on,
        # offline: every frame mapped; realtime: frames_dropped and lag_* say what was not
        "pace": sensor.pace,
        "max_lag_s": float(cfg.mapping.max_lag_s),
        "pose_source": pose_source.name,
        "oracles": oracles_used(cfg),
        "perception": mapper.points.perception_summary(),
        # a replay's damaged frames (skipped, listed) and dropped tail; absent otherwise
        **({"replay": damage} if (damage := sensor.damage_report()) else {}),
        **pose_source.metrics(),
        # a producer that failed mid-run (the run kept what it had mapped)
        **({"error": _one_line(session.failure)} if session.failure is not None else {}),
        "config": {
            "object": cfg.object.name,
            "sensor": cfg.sensor.name,
            "model": session.model_config,
            "classifier": cfg.classifier.get("_target_"),
            "fingers": list(cfg.sensor.get("fingers", [])) if "fingers" in cfg.sensor else None,
            "seed": int(cfg.seed),
            "resumed_from": cfg.mapping.resume,
            # A generated object (object=random): seed, sub-seed used, family, layout.
            "object_generation": getattr(obj, "generation", None),
            # A custom mesh with a drawn layout (object.layout_seed): mesh, seed, layout.
            "object_layout": getattr(obj, "layout", None),
        },
    }


def _one_line(error: BaseException) -> str:
    lines = str(error).strip().splitlines()
    return f"{type(error).__name__}: {lines[0] if lines else ''}".rstrip(": ")


def _failed(error: BaseException, metrics: dict, out: Path) -> BaseException:
    """What a run whose producer failed ends with: its own user error, or one line naming
    the failure (traceback in the log), after the outputs were written."""
    kept = (
        f"after frame {metrics['frames_total'] - 1}: checkpoint, partial metrics.json, "
        f"touches.csv and pictures are in {out}; continue with mapping.resume={out / 'checkpoint.pt'}"
    )
    if isinstance(error, UserError):
        log.warning("the run stopped %s", kept)
        return error
    log.error("the frame producer failed", exc_info=error)
    return FrameSourceError(f"the frame producer failed ({_one_line(error)}) {kept}")


def _interrupted(metrics: dict, out: Path) -> Interrupted:
    """The one line a signal-stopped run ends with: what was kept, where, how to go on."""
    name = metrics["stopped_by"]
    return Interrupted(
        signal.Signals[name],
        f"interrupted ({name}) after frame {metrics['frames_total'] - 1}: "
        f"checkpoint, partial metrics.json, touches.csv and pictures are in {out}; "
        f"continue with mapping.resume={out / 'checkpoint.pt'}",
    )
