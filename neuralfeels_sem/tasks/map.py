"""task=map (the default): stream frames, classify touches, train the field online, score it.

    python run.py sensor=sim object=plushie
    python run.py object=patched_toy mapping.resume=outputs/map/.../checkpoint.pt

Writes the run-output contract of docs/design.md into the run directory: metrics.json,
material_mesh.ply, matching_curve.png, material_maps.png, progression.png,
checkpoint.pt (every mapping.checkpoint_every frames and at the end) and touches.csv.
"""

from __future__ import annotations

import csv
import json
import logging
import os
import platform
import time
from pathlib import Path

import numpy as np
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from neuralfeels_sem.configs import to_config
from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.eval.run_scorer import RunScorer
from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.pose_source import build_pose_source
from neuralfeels_sem.mapping.pose_tracker import TrackerConfig
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.runner import output_dir
from neuralfeels_sem.utils.device import resolve_device
from neuralfeels_sem.viz.run_report import print_summary, write_pictures

log = logging.getLogger(__name__)

# The field's half-extent is BOUND_MARGIN times the object's bounding radius (computed per
# object, not a setting): the truncation band and free-space samples just outside the
# surface must stay inside the hash grid.
BOUND_MARGIN = 1.15


def build_scorer(cfg: DictConfig, obj) -> RunScorer:
    e = cfg.eval
    return RunScorer(
        obj,
        num_surface_samples=e.num_surface_samples,
        image_views=e.image_views,
        image_size=e.image_size,
        image_elevation_deg=e.image_elevation_deg,
        fscore_thresholds_mm=list(e.fscore_thresholds_mm),
        shape_samples=e.shape_samples,
        mesh_resolution=e.mesh_resolution,
        seed=e.seed,
        mesh_match_tolerance_m=e.mesh_match_tolerance_m,
    )


def build_mapper(cfg: DictConfig, bound: float, device) -> OnlineMapper:
    """The field (cube half-extent `bound`, from the object) and its online mapper."""
    field = SemanticField(to_config(SemanticFieldConfig, cfg.model), bound)
    optimizer_factory = instantiate(cfg.mapping.optimizer)  # a partial FieldAdam
    return OnlineMapper(
        to_config(MapperConfig, cfg.mapping.mapper), field, optimizer_factory, device
    )


def oracles_used(cfg: DictConfig) -> list[str]:
    """The simulator's ground truth a run's perception or pose used (a real rig has none)."""
    if cfg.sensor.name != "sim":
        return []
    mapper = cfg.mapping.mapper
    used = {
        "object_pose": cfg.mapping.pose == "gt",
        "camera_mask": bool(mapper.get("use_camera_mask", False)),
        "tactile_contact_depth": mapper.get("tactile_depth", {}).get("source") == "gt",
        "noise_free_depth": float(cfg.sensor.get("rgbd", {}).get("depth_noise_std", 0.0)) == 0.0,
        "material_labels": str(cfg.classifier.get("_target_", "")).endswith("OracleClassifier"),
    }
    return [name for name, on in used.items() if on]


def machine_info(device) -> dict:
    """What a timing depends on: the machine, its load and the threads torch used."""
    import torch

    return {
        "cpu": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "device": str(device),
    }


def model_config(cfg: DictConfig) -> dict:
    return OmegaConf.to_container(cfg.model, resolve=True)


def run(cfg: DictConfig) -> dict:
    class_names = list(cfg.materials)
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, class_names)
    sensor.open()  # a missing device ends the run here, before any heavy work
    try:
        return map_object(cfg, obj, sensor, output_dir())
    finally:
        sensor.close()


def map_object(cfg: DictConfig, obj, sensor, out: Path) -> dict:
    """The mapping loop over an opened sensor; writes every run output into `out`."""
    class_names = list(cfg.materials)
    classifier = instantiate(cfg.classifier)
    device = resolve_device(cfg.device)
    bound = BOUND_MARGIN * obj.bounds_radius
    mapper = build_mapper(cfg, bound, device)
    model_cfg = model_config(cfg)  # what a checkpoint must match to resume
    scorer = build_scorer(cfg, obj)
    # A PoseTracker is built only when mapping.pose tracks.
    tracker = to_config(TrackerConfig, cfg.mapping.tracker)
    pose_source = build_pose_source(cfg.mapping.pose, obj, tracker)
    snapshots_dir = out / "progression"
    snapshots_dir.mkdir(exist_ok=True)

    baseline, _ = scorer.field_metrics(mapper.field, bound)
    majority = scorer.majority_baseline()
    log.info(
        "floors: majority-material map %.1f%% mean-class / %.1f%% matching; untrained field %.1f%% / %.1f%%",
        majority.get("matching_mean_class_pct", float("nan")),
        majority.get("matching_pct", float("nan")),
        baseline.get("matching_mean_class_pct", float("nan")),
        baseline.get("matching_pct", float("nan")),
    )

    start_index = -1
    if cfg.mapping.resume:
        resumed = load_checkpoint(cfg.mapping.resume, mapper, model_cfg)
        start_index = resumed["frame_index"]
        scorer.load_state(resumed["extra"].get("scorer", {}))
        pose_source.load_state(resumed["extra"].get("pose", {}))
        log.info("resumed from %s after frame %d", cfg.mapping.resume, start_index)

    every_k = int(cfg.eval.every_k_frames)
    checkpoint_every = int(cfg.mapping.checkpoint_every)
    checkpoint_path = out / "checkpoint.pt"
    processed = 0
    first_time = last_time = None
    last_index = start_index
    total = len(sensor) if len(sensor) > 0 else None
    frame_period = float(getattr(sensor, "frame_period_s", 0.0))
    snapshot_every = max(1, (total or 100) // max(1, int(cfg.viz.progression_snapshots)))
    wall_start = time.perf_counter()
    bar = tqdm(total=total, desc="map", unit="frame", dynamic_ncols=True)
    for frame in sensor.frames():
        bar.update(1)
        if frame.index <= start_index:
            continue  # already in the checkpoint
        readings = list(frame.tactile.values())
        labels = (
            {r.finger: lab for r, lab in zip(readings, classifier.classify(readings))}
            if readings
            else {}
        )
        scorer.log_touches(frame, labels)
        world_T_object = pose_source.estimate(frame, mapper)
        mapper.add_frame(frame, labels, world_T_object=world_T_object)
        processed += 1
        last_index = frame.index
        first_time = frame.time_s if first_time is None else first_time
        last_time = frame.time_s
        is_last = total is not None and frame.index == total - 1
        if frame.index % every_k == 0 or is_last:
            scores = scorer.score(
                mapper.field, frame.index, frame.time_s, pose_source.field_T_gt_object()
            )
            elapsed = time.perf_counter() - wall_start
            bar.set_postfix(
                t=f"{frame.time_s:.1f}s",
                fps=f"{processed / max(elapsed, 1e-9):.2f}",
                mean_class="n/a" if scores is None else f"{scores['matching_mean_class_pct']:.1f}%",
            )
        if frame.index % snapshot_every == 0 or is_last:
            take_snapshot(
                scorer,
                mapper.field,
                frame.time_s,
                frame.index,
                snapshots_dir,
                pose_source.field_T_gt_object(),
            )
        if checkpoint_every and frame.index % checkpoint_every == 0:
            save_checkpoint(
                checkpoint_path,
                mapper,
                frame.index,
                {"scorer": scorer.state(), "pose": pose_source.state()},
                model_cfg,
            )
    bar.close()
    wall_s = time.perf_counter() - wall_start

    trained_on = mapper.trained_on
    if (
        trained_on["optimizer_steps"] == 0
        or (trained_on["camera_points"] + trained_on["tactile_points"]) == 0
    ):
        raise NoDataError(
            f"the field received no data in {trained_on['frames']} frames (no camera or tactile points); "
            "check that the object is in view and the fingers touch it (sensor config)"
        )
    save_checkpoint(
        checkpoint_path,
        mapper,
        last_index,
        {"scorer": scorer.state(), "pose": pose_source.state()},
        model_cfg,
    )
    if not scorer.curve or scorer.curve[-1][0] != last_index:
        scorer.score(mapper.field, last_index, last_time or 0.0, pose_source.field_T_gt_object())

    scores, mesh = scorer.final_metrics(
        mapper.field, bound, baseline, pose_source.field_T_gt_object()
    )
    if mesh is not None:
        mesh.export(out / "material_mesh.ply")
    sensor_time = (last_time - first_time + frame_period) if first_time is not None else 0.0
    metrics = {
        **scores,
        "frames": processed,
        "frames_total": last_index + 1,
        "wall_s": wall_s,
        "sensor_time_s": sensor_time,
        "realtime_factor": sensor_time / wall_s if wall_s > 0 else None,
        "machine": machine_info(device),
        "load_avg": [round(x, 2) for x in os.getloadavg()],  # 1, 5, 15 min at the end
        "trained_on": trained_on,
        "pose_source": pose_source.name,
        "oracles": oracles_used(cfg),
        **pose_source.metrics(),
        "config": {
            "object": cfg.object.name,
            "sensor": cfg.sensor.name,
            "model": model_cfg,
            "classifier": cfg.classifier.get("_target_"),
            "fingers": list(cfg.sensor.get("fingers", [])) if "fingers" in cfg.sensor else None,
            "seed": int(cfg.seed),
            "resumed_from": cfg.mapping.resume,
        },
    }
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, default=_json_default))
    write_touches(scorer.touch_log, class_names, out / "touches.csv")
    if cfg.viz.plots:
        write_pictures(scorer.class_names, metrics, snapshots_dir, out, int(cfg.viz.dpi))
        pose_source.write_pictures(out, int(cfg.viz.dpi))
    print_summary(metrics, out)
    return metrics


def take_snapshot(
    scorer: RunScorer,
    field,
    time_s: float,
    frame_index: int,
    directory: Path,
    field_T_gt: np.ndarray,
) -> None:
    """Progression snapshots go to disk at once, so a resumed run still has the early ones."""
    maps = scorer.snapshot(field, field_T_gt)
    if maps is None:
        return
    np.savez_compressed(
        directory / f"{frame_index:06d}.npz",
        time_s=time_s,
        gt=maps["gt"],
        pred=maps["pred"],
        diff=maps["diff"],
        shade=maps["shade"],
        matching_pct_image=maps["matching_pct_image"],
    )


def write_touches(touch_log: list[list], class_names: list[str], path: Path) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["frame", "finger", "predicted", "ground_truth", "confidence"])
        for frame, finger, predicted, gt, confidence in touch_log:
            writer.writerow(
                [
                    frame,
                    finger,
                    class_names[predicted] if predicted >= 0 else "none",
                    class_names[gt] if gt >= 0 else "unknown",
                    f"{confidence:.3f}",
                ]
            )


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
