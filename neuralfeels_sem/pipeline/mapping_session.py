"""One mapping run over an opened sensor: the frame loop behind `task=map`.

Per frame: classify the touches, log them for the classifier figures, estimate the object
pose, add the frame to the mapper (which trains the field); every `every_k_frames` frames
(and on the last) score the field, every len/`progression_snapshots` frames write a
progression snapshot, every `checkpoint_every` frames write checkpoint.pt. A run resumed
from a checkpoint skips the frames it already holds and continues where it stopped, with
the scorer's curve and the pose source's state restored. At the end: the final checkpoint,
the final scores and the coloured mesh.
"""

from __future__ import annotations

import logging
import time
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
from neuralfeels_sem.sensors.base import Sensor

log = logging.getLogger(__name__)


@dataclass
class SessionSettings:
    """Cadences of a session (from eval.every_k_frames, mapping.checkpoint_every,
    viz.progression_snapshots)."""

    every_k_frames: int
    checkpoint_every: int  # 0: only the final checkpoint
    progression_snapshots: int


@dataclass
class _Progress:
    """What the loop saw: frames processed, the last index and the sensor times."""

    processed: int = 0
    last_index: int = -1
    first_time: float | None = None
    last_time: float | None = None


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
    ) -> None:
        self.mapper = mapper
        self.classifier = classifier
        self.scorer = scorer
        self.pose_source = pose_source
        self.out = out
        self.bound = bound
        self.model_config = model_config
        self.settings = settings
        self.checkpoint_path = out / "checkpoint.pt"
        self.snapshots_dir = out / "progression"

    def run(self, sensor: Sensor, resume: str | None = None) -> dict:
        """Map every frame of the opened `sensor`; returns the scores, frame counts and timing.

        `resume`: a checkpoint of an earlier run of the same config to continue from.
        Raises NoDataError when the field received no camera or tactile point.
        """
        self.snapshots_dir.mkdir(exist_ok=True)
        baseline = self._floors()
        start_index = self._resume(resume) if resume else -1
        frame_period = float(getattr(sensor, "frame_period_s", 0.0))
        wall_start = time.perf_counter()
        progress = self._loop(sensor, start_index, wall_start)
        wall_s = time.perf_counter() - wall_start
        scores = self._finish(progress, baseline)
        first, last = progress.first_time, progress.last_time
        sensor_time = (last - first + frame_period) if first is not None else 0.0
        return {
            **scores,
            "frames": progress.processed,
            "frames_total": progress.last_index + 1,
            "wall_s": wall_s,
            "sensor_time_s": sensor_time,
            "realtime_factor": sensor_time / wall_s if wall_s > 0 else None,
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
        """Restore mapper, scorer and pose source from `path`; the last frame it holds."""
        resumed = load_checkpoint(path, self.mapper, self.model_config)
        self.scorer.load_state(resumed["extra"].get("scorer", {}))
        self.pose_source.load_state(resumed["extra"].get("pose", {}))
        log.info("resumed from %s after frame %d", path, resumed["frame_index"])
        return resumed["frame_index"]

    def _loop(self, sensor: Sensor, start_index: int, wall_start: float) -> _Progress:
        total = len(sensor) if len(sensor) > 0 else None
        snapshot_every = max(1, (total or 100) // max(1, self.settings.progression_snapshots))
        progress = _Progress(last_index=start_index)
        bar = tqdm(total=total, desc="map", unit="frame", dynamic_ncols=True)
        for frame in sensor.frames():
            bar.update(1)
            if frame.index <= start_index:
                continue  # already in the checkpoint
            self._add(frame, progress)
            is_last = total is not None and frame.index == total - 1
            if frame.index % self.settings.every_k_frames == 0 or is_last:
                scores = self._score(frame.index, frame.time_s)
                elapsed = time.perf_counter() - wall_start
                bar.set_postfix(
                    t=f"{frame.time_s:.1f}s",
                    fps=f"{progress.processed / max(elapsed, 1e-9):.2f}",
                    mean_class="n/a"
                    if scores is None
                    else f"{scores['matching_mean_class_pct']:.1f}%",
                )
            if frame.index % snapshot_every == 0 or is_last:
                self._snapshot(frame.time_s, frame.index)
            every = self.settings.checkpoint_every
            if every and frame.index % every == 0:
                self._checkpoint(frame.index)
        bar.close()
        return progress

    def _add(self, frame: Frame, progress: _Progress) -> None:
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
        progress.processed += 1
        progress.last_index = frame.index
        if progress.first_time is None:
            progress.first_time = frame.time_s
        progress.last_time = frame.time_s

    def _score(self, frame_index: int, time_s: float) -> dict | None:
        field_T_gt = self.pose_source.field_T_gt_object()
        return self.scorer.score(self.mapper.field, frame_index, time_s, field_T_gt)

    def _checkpoint(self, frame_index: int) -> None:
        extra = {"scorer": self.scorer.state(), "pose": self.pose_source.state()}
        save_checkpoint(self.checkpoint_path, self.mapper, frame_index, extra, self.model_config)

    def _snapshot(self, time_s: float, frame_index: int) -> None:
        """Progression snapshots go to disk at once, so a resumed run still has the early ones."""
        maps = self.scorer.snapshot(self.mapper.field, self.pose_source.field_T_gt_object())
        if maps is None:
            return
        np.savez_compressed(
            self.snapshots_dir / f"{frame_index:06d}.npz",
            time_s=time_s,
            gt=maps["gt"],
            pred=maps["pred"],
            diff=maps["diff"],
            shade=maps["shade"],
            matching_pct_image=maps["matching_pct_image"],
        )

    def _finish(self, progress: _Progress, baseline: dict) -> dict:
        """Fail on a field that saw no data; final checkpoint, scores and mesh."""
        trained_on = self.mapper.trained_on
        if (
            trained_on["optimizer_steps"] == 0
            or (trained_on["camera_points"] + trained_on["tactile_points"]) == 0
        ):
            raise NoDataError(
                f"the field received no data in {trained_on['frames']} frames (no camera or tactile points); "
                "check that the object is in view and the fingers touch it (sensor config)"
            )
        self._checkpoint(progress.last_index)
        curve = self.scorer.curve
        if not curve or curve[-1][0] != progress.last_index:
            self._score(progress.last_index, progress.last_time or 0.0)
        scores, mesh = self.scorer.final_metrics(
            self.mapper.field, self.bound, baseline, self.pose_source.field_T_gt_object()
        )
        if mesh is not None:
            mesh.export(self.out / "material_mesh.ply")
        return scores
