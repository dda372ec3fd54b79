"""One mapping run over an opened sensor: the frame loop behind `task=map`.

Per frame: classify the touches, log them for the classifier figures, estimate the object
pose, add the frame to the mapper (which trains the field); every `every_k_frames` frames
(and on the last) score the field, every len/`progression_snapshots` frames write a
progression snapshot, every `checkpoint_every` frames write checkpoint.pt. A run resumed
from a checkpoint skips the frames it already holds and continues where it stopped, with
the scorer's curve, the pose source's state and the earlier segments' frame counts and
wall times restored. SIGINT or SIGTERM stops the loop after the frame in progress (the
result is then marked partial). At the end: the final checkpoint, the final scores and
the coloured mesh. Every file is written atomically.
"""

from __future__ import annotations

import logging
import shutil
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.eval.run_scorer import RunScorer
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.mapping.mapper import OnlineMapper
from neuralfeels_sem.mapping.pose_source import PoseSource
from neuralfeels_sem.mapping.provenance import Provenance
from neuralfeels_sem.pipeline.interrupts import Interrupted, StopOnSignal
from neuralfeels_sem.pipeline.observers import FrameObserver
from neuralfeels_sem.pipeline.segments import Segment, load_segments, run_totals
from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.utils.atomic import atomic_write

log = logging.getLogger(__name__)


@dataclass
class SessionSettings:
    """Cadences of a session (from eval.every_k_frames, mapping.checkpoint_every,
    viz.progression_snapshots)."""

    every_k_frames: int
    checkpoint_every: int  # 0: only the final checkpoint
    progression_snapshots: int


class MappingSession:
    """Frames -> classified touches -> pose -> mapper, scored on the way.

    Args:
        mapper: the online mapper (its field is the one scored).
        classifier: has `classify(readings) -> labels`, one per tactile reading.
        scorer: the run's scorer (curve, touch log, snapshots, final figures).
        pose_source: where each frame's object pose comes from (gt or tracked).
        out: the run directory (checkpoint.pt, progression/, material_mesh.ply).
        bound: the field's half-extent (for the mesh extraction and the floors).
        model_config: what a checkpoint must match to resume (the composed model config).
        provenance: the object, sensor, classes and model each checkpoint records.
        observers: told of every mapped frame and scoring pass (pipeline/observers.py).
    """

    def __init__(
        self,
        mapper: OnlineMapper,
        classifier,
        scorer: RunScorer,
        pose_source: PoseSource,
        out: Path,
        bound: float,
        model_config: dict,
        settings: SessionSettings,
        provenance: Provenance | None = None,
        observers: Sequence[FrameObserver] = (),
    ) -> None:
        self.mapper = mapper
        self.classifier = classifier
        self.scorer = scorer
        self.pose_source = pose_source
        self.out = out
        self.bound = bound
        self.model_config = model_config
        self.settings = settings
        self.provenance = provenance
        self.observers = list(observers)
        self.earlier_segments: list[Segment] = []  # of the run this one resumes
        self.segment = Segment()
        self.last_index = -1
        self.stop = StopOnSignal(out)
        self.checkpoint_path = out / "checkpoint.pt"
        self.snapshots_dir = out / "progression"

    def run(self, sensor: Sensor, resume: str | None = None) -> dict:
        """Map every frame of the opened `sensor`; returns the scores, frame counts and timing.

        `resume`: a checkpoint of an earlier run of the same config to continue from.
        Frames, wall time and sensor time cover every segment of the run. `partial` is
        True (and `stopped_by` the signal's name) when SIGINT or SIGTERM stopped it.
        Raises NoDataError when the field received no camera or tactile point.
        """
        self.snapshots_dir.mkdir(exist_ok=True)
        baseline = self._floors()
        self.last_index = self._resume(resume) if resume else -1
        frame_period = float(getattr(sensor, "frame_period_s", 0.0))
        with self.stop:
            wall_start = time.perf_counter()
            try:
                self._loop(sensor, wall_start)
            finally:
                for observer in self.observers:
                    observer.close()
            self.segment.wall_s = time.perf_counter() - wall_start
            self.segment.partial = self.stop.requested
            scores = self._finish(baseline)
        totals = run_totals([*self.earlier_segments, self.segment], frame_period)
        return {
            **scores,
            **totals,
            "frames_total": self.last_index + 1,
            # A signal during the final scoring, after the last frame, leaves the run complete.
            "partial": self.segment.partial,
            "stopped_by": signal.Signals(self.stop.signum).name if self.segment.partial else None,
        }

    def _floors(self) -> dict:
        """The untrained field's figures (returned) and the majority map's (logged)."""
        baseline, _ = self.scorer.field_metrics(self.mapper.field, self.bound)
        majority = self.scorer.majority_baseline()
        log.info(
            "floors: majority-material map %.1f%% mean-class / %.1f%% matching; untrained field %.1f%% / %.1f%%",
            majority.get("matching_mean_class_pct", float("nan")),
            majority.get("matching_pct", float("nan")),
            baseline.get("matching_mean_class_pct", float("nan")),
            baseline.get("matching_pct", float("nan")),
        )
        return baseline

    def _resume(self, path: str) -> int:
        """Restore mapper, scorer, pose source and segments from `path`; its last frame."""
        resumed = load_checkpoint(path, self.mapper, self.model_config)
        extra = resumed["extra"]
        self.scorer.load_state(extra.get("scorer", {}))
        self.pose_source.load_state(extra.get("pose", {}))
        self.earlier_segments = load_segments(extra.get("segments", []))
        self._copy_snapshots(Path(path).parent / "progression", resumed["frame_index"])
        log.info("resumed from %s after frame %d", path, resumed["frame_index"])
        return resumed["frame_index"]

    def _copy_snapshots(self, source: Path, last_frame: int) -> None:
        """A run resumed into another directory takes the snapshots its checkpoint covers."""
        if not source.is_dir() or source.resolve() == self.snapshots_dir.resolve():
            return
        for path in sorted(source.glob("*.npz")):
            if path.stem.isdigit() and int(path.stem) <= last_frame:
                shutil.copy2(path, self.snapshots_dir / path.name)

    def _loop(self, sensor: Sensor, wall_start: float) -> None:
        total = len(sensor) if len(sensor) > 0 else None
        snapshot_every = max(1, (total or 100) // max(1, self.settings.progression_snapshots))
        start_index = self.last_index
        bar = tqdm(total=total, desc="map", unit="frame", dynamic_ncols=True)
        for frame in sensor.frames():
            bar.update(1)
            if frame.index <= start_index:
                continue  # already in the checkpoint
            self._add(frame)
            is_last = total is not None and frame.index == total - 1
            if frame.index % self.settings.every_k_frames == 0 or is_last:
                scores = self._score(frame.index, frame.time_s)
                for observer in self.observers:
                    observer.on_scores(frame.index, scores, self.mapper)
                elapsed = time.perf_counter() - wall_start
                bar.set_postfix(
                    t=f"{frame.time_s:.1f}s",
                    fps=f"{self.segment.frames / max(elapsed, 1e-9):.2f}",
                    mean_class="n/a"
                    if scores is None
                    else f"{scores['matching_mean_class_pct']:.1f}%",
                )
            if frame.index % snapshot_every == 0 or is_last:
                self._snapshot(frame.time_s, frame.index)
            every = self.settings.checkpoint_every
            if every and frame.index % every == 0:
                self.segment.wall_s = time.perf_counter() - wall_start
                self._checkpoint()
            if self.stop.requested:
                break  # the frame in progress is done: nothing is lost
        bar.close()

    def _add(self, frame: Frame) -> None:
        """Classify the frame's touches, estimate its pose and give it to the mapper."""
        readings = list(frame.tactile.values())
        labels = (
            {r.finger: lab for r, lab in zip(readings, self.classifier.classify(readings))}
            if readings
            else {}
        )
        self.scorer.log_touches(frame, labels)
        world_T_object = self.pose_source.estimate(frame, self.mapper)
        self.mapper.add_frame(frame, labels, world_T_object=world_T_object)
        self.segment.add_frame(frame.index, frame.time_s)
        self.last_index = frame.index
        for observer in self.observers:
            observer.on_frame(frame, labels, world_T_object, self.mapper)

    def _score(self, frame_index: int, time_s: float) -> dict | None:
        field_T_gt = self.pose_source.field_T_gt_object()
        return self.scorer.score(self.mapper.field, frame_index, time_s, field_T_gt)

    def _checkpoint(self) -> None:
        """checkpoint.pt after `self.last_index`, with the segments up to now."""
        extra = {
            "scorer": self.scorer.state(),
            "pose": self.pose_source.state(),
            "segments": [s.to_dict() for s in (*self.earlier_segments, self.segment)],
        }
        save_checkpoint(
            self.checkpoint_path,
            self.mapper,
            self.last_index,
            extra,
            self.model_config,
            self.provenance,
        )

    def _snapshot(self, time_s: float, frame_index: int) -> None:
        """Progression snapshots go to disk at once, so a resumed run still has the early ones."""
        maps = self.scorer.snapshot(self.mapper.field, self.pose_source.field_T_gt_object())
        if maps is None:
            return
        with atomic_write(self.snapshots_dir / f"{frame_index:06d}.npz", "wb") as f:
            np.savez_compressed(
                f,
                time_s=time_s,
                gt=maps["gt"],
                pred=maps["pred"],
                diff=maps["diff"],
                shade=maps["shade"],
                entropy=maps["entropy"],
                matching_pct_image=maps["matching_pct_image"],
            )

    def _finish(self, baseline: dict) -> dict:
        """Fail on a field that saw no data; final checkpoint, scores and mesh."""
        trained_on = self.mapper.trained_on
        if (
            trained_on["optimizer_steps"] == 0
            or (trained_on["camera_points"] + trained_on["tactile_points"]) == 0
        ):
            if self.stop.requested:
                raise Interrupted(
                    self.stop.signum,
                    f"interrupted ({signal.Signals(self.stop.signum).name}) before the field "
                    f"received any data; nothing to keep in {self.out}",
                )
            raise NoDataError(
                f"the field received no data in {trained_on['frames']} frames (no camera or tactile points); "
                "check that the object is in view and the fingers touch it (sensor config)"
            )
        self._checkpoint()  # first: a second signal must not lose the frames
        curve = self.scorer.curve
        if not curve or curve[-1][0] != self.last_index:
            self._score(self.last_index, self.segment.last_time_s or 0.0)
        scores, mesh = self.scorer.final_metrics(
            self.mapper.field, self.bound, baseline, self.pose_source.field_T_gt_object()
        )
        if mesh is not None:
            with atomic_write(self.out / "material_mesh.ply", "wb") as f:
                mesh.export(f, file_type="ply")
        return scores
