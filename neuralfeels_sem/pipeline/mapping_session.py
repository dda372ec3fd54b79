"""One mapping run over an opened sensor: the frame loop behind `task=map`.

A producer thread (producer.py) acquires or renders each frame, classifies its touches and runs the
perception that needs no field (camera segmentation, tactile depth); this side, the mapper's, takes
its frames from a bounded queue: logs the touches, estimates the object pose, adds the frame to the
mapper (which trains the field) and tells the observers. At sensor.pace=offline every frame is
mapped, in order, as by a sequential loop; at realtime the frames come at the sensor's clock, the
mapper takes the newest one, drops any due more than `max_lag_s` ago and counts them (pace.py), and
runs single steps while no new frame has come. Every `every_k_frames` frames (and on the last) the
field is scored and every len/`progression_snapshots` frames a progression snapshot is written, on a
copy of the field by a worker thread (background_eval.py); every `checkpoint_every` frames (later
while the last write runs) the mapper's state is copied here and written by another worker
(checkpoint_writer.py). A resumed run skips the frames its checkpoint holds and continues where it
stopped, with the scorer's curve, the pose source's state and the earlier segments' frame counts
and wall times restored. SIGINT or SIGTERM stops the loop after the frame in progress (the result
is then partial); a failed producer ends it the same way and `failure` holds its error. At the end:
the final checkpoint, the final scores and the coloured mesh. Every file is written atomically.
"""

from __future__ import annotations

import logging
import shutil
import signal
import time
from collections.abc import Sequence
from pathlib import Path

from tqdm import tqdm

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.eval.run_scorer import RunScorer
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, prepare_checkpoints, take_checkpoint
from neuralfeels_sem.mapping.mapper import OnlineMapper
from neuralfeels_sem.mapping.pose_source import PoseSource
from neuralfeels_sem.mapping.provenance import Provenance
from neuralfeels_sem.pipeline.background_eval import BackgroundEval
from neuralfeels_sem.pipeline.checkpoint_writer import CheckpointWriter
from neuralfeels_sem.pipeline.interrupts import Interrupted, StopOnSignal
from neuralfeels_sem.pipeline.observers import FrameObserver
from neuralfeels_sem.pipeline.pace import PerceivedFrame, StreamEnd
from neuralfeels_sem.pipeline.producer import FrameProducer
from neuralfeels_sem.pipeline.run_outputs import write_snapshot
from neuralfeels_sem.pipeline.segments import Segment, load_segments, run_totals
from neuralfeels_sem.pipeline.session_settings import SessionSettings
from neuralfeels_sem.pipeline.touch_frames import OvertakenTouches
from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.utils.atomic import atomic_write

log = logging.getLogger(__name__)


class MappingSession:
    """Frames -> classified touches -> pose -> mapper, scored on the way.

    Args:
        mapper: the online mapper (its field is the one scored).
        classifier: has `open()` and `classify(readings) -> labels` (one per reading).
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
        self.failure: BaseException | None = None  # the producer's error, if it failed
        self.background: BackgroundEval | None = None  # scoring off the mapper's path
        self.overtaken = OvertakenTouches(self.settings.overtaken_touch_frames > 0)
        self.writer: CheckpointWriter | None = None  # checkpoint writes off the mapper's path
        self.stop = StopOnSignal(out)
        self.checkpoint_path, self.snapshots_dir = out / "checkpoint.pt", out / "progression"

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
        self.writer = CheckpointWriter(self.checkpoint_path, self.settings.nice_at(sensor.pace))
        self.classifier.open()  # loaded before the clock starts (on a GPU: graph captures),
        self.mapper.points.load_models()  # in the order the first frame would load them
        prepare_checkpoints(self.mapper)  # and what the first checkpoint would draw
        try:
            with self.stop:
                wall_start, cpu_start = time.perf_counter(), time.thread_time()
                try:
                    self._loop(sensor, wall_start)
                finally:
                    for observer in self.observers:
                        observer.close()
                self.segment.wall_s = time.perf_counter() - wall_start
                self.segment.mapper_cpu_s = time.thread_time() - cpu_start
                self.segment.partial = self.stop.requested or self.failure is not None
                scores = self._finish(baseline)
        finally:
            writer, self.writer = self.writer, None
            writer.close()
        totals = run_totals([*self.earlier_segments, self.segment], frame_period)
        return {
            **scores,
            **totals,
            "frames_total": self.last_index + 1,
            # A signal during the final scoring, after the last frame, leaves the run complete.
            "partial": self.segment.partial,
            "stopped_by": self._stopped_by(),
        }

    def _stopped_by(self) -> str | None:
        """The signal's name, `error` for a failed producer, None for a complete run."""
        if not self.segment.partial:
            return None
        return "error" if self.failure is not None else signal.Signals(self.stop.signum).name

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
        points, nice = self.mapper.points, self.settings.nice_at(sensor.pace)
        producer = FrameProducer(sensor, self.classifier.classify, points.perceive, points.forget,
                                 self.last_index, self.settings.acquire_thread, nice,
                                 self.settings.overtaken_touch_frames)  # fmt: skip
        bar = tqdm(total=total, desc="map", unit="frame", dynamic_ncols=True)
        bar.update(self.last_index + 1)
        self.background = BackgroundEval(self.scorer, self._write_snapshot, nice)
        producer.start()
        try:
            while not self.stop.requested:
                item = producer.queue.get(timeout=0.0 if self._idle_steps(producer) else 0.1)
                self._show_scores(self.background.collect() if self.background else [], bar)
                if item is None:
                    continue
                self.segment.frames_dropped += item.dropped_before
                bar.update(item.dropped_before + isinstance(item, PerceivedFrame))
                if isinstance(item, StreamEnd):
                    self._end_of_stream(item, total if producer.clock is not None else None, bar)
                    break
                if self._too_late(producer, item):
                    continue
                realtime = producer.clock is not None
                self._map(item, realtime, total, snapshot_every, wall_start, bar)
        finally:
            producer.stop()
            self.segment.record_producer(producer.cpu_s, producer.stage_cpu_s)
            self._close_background(bar)
            bar.close()

    def _drain_background(self, bar) -> None:
        if self.background is not None:
            self._show_scores(self.background.drain(), bar)

    def _close_background(self, bar) -> None:
        """Wait for the realtime scoring passes still running and report them."""
        if self.background is not None:
            background, self.background = self.background, None
            try:
                self._show_scores(background.drain(), bar)
            finally:
                background.close()

    def _show_scores(self, passes: list, bar) -> None:
        """Tell the observers of finished scoring passes and show the latest on the bar."""
        for frame_index, time_s, scores in passes:
            for observer in self.observers:
                observer.on_scores(frame_index, scores, self.mapper)
            bar.set_postfix(
                t=f"{time_s:.1f}s",
                fps=f"{self.segment.frames / max(self.segment.wall_s, 1e-9):.2f}",
                mean_class="n/a" if scores is None else f"{scores['matching_mean_class_pct']:.1f}%",
            )

    def _idle_steps(self, producer: FrameProducer) -> bool:
        """Realtime: one optimiser step while no new frame has come (True: one ran)."""
        if producer.clock is None or not self.mapper.has_surface:
            return False
        if producer.queue.ready():
            return False
        self.mapper.optimize(1)
        self.segment.idle_steps += 1
        return True

    def _too_late(self, producer: FrameProducer, item: PerceivedFrame) -> bool:
        """Realtime: drop (and count) a frame due more than max_lag_s ago; note the lag of
        one taken."""
        if producer.clock is None:
            return False
        lag = producer.clock.lag(item.frame.index)
        if lag > self.settings.max_lag_s:
            self.segment.frames_dropped += 1
            if not self.overtaken.carry(item):
                self.mapper.points.forget(item.frame)
            return True
        self.segment.add_lag(max(0.0, lag))
        return False

    def _end_of_stream(self, end: StreamEnd, realtime_total: int | None, bar) -> None:
        """A failed producer's error is kept; a realtime stream whose last frames were
        dropped (`realtime_total`: the sensor's frame count) is scored and snapshotted at
        the last frame mapped."""
        if end.error is not None:
            self.failure = end.error
            return
        last_time_s = self.segment.last_time_s
        total = realtime_total
        if total is None or not 0 <= self.last_index < total - 1 or last_time_s is None:
            return
        self._close_background(bar)
        curve = self.scorer.curve
        if not curve or curve[-1][0] != self.last_index:
            self._show_scores(
                [(self.last_index, last_time_s, self._score(self.last_index, last_time_s))], bar
            )
            self._snapshot(last_time_s, self.last_index)

    def _map(
        self,
        item: PerceivedFrame,
        realtime: bool,
        total: int | None,
        snapshot_every: int,
        wall_start: float,
        bar,
    ) -> None:
        """Map one frame, then score, snapshot and checkpoint where their cadence falls."""
        frame, previous = item.frame, self.last_index
        # Realtime: no warm-up block (the world does not wait); idle steps make up for it.
        steps = self.mapper.config.steps_per_frame if realtime else None
        self._add(frame, item.labels, steps, item.touches)
        is_last = total is not None and frame.index == total - 1

        def crossed(every: int) -> bool:  # a multiple of `every` reached (or passed: realtime)
            return frame.index // every > previous // every

        self.segment.wall_s = time.perf_counter() - wall_start
        score = crossed(self.settings.every_k_frames) or is_last
        snapshot = crossed(snapshot_every) or is_last
        if score or snapshot:
            field_T_gt = self.pose_source.field_T_gt_object()
            self.background.submit(
                self.mapper.field, frame.index, frame.time_s, field_T_gt, score, snapshot
            )
        every = self.settings.checkpoint_every
        # Realtime maps a frame now and then: a checkpoint every `every` frames mapped.
        reached = bool(every) and (self.segment.frames % every == 0 if realtime else crossed(every))
        if self.writer.due(reached):
            self._drain_background(bar)  # the checkpoint records the scorer's curves
            self._checkpoint()

    def _add(self, frame: Frame, labels: dict, steps: int | None, touches: list = ()) -> None:
        """Log the frame's classified touches, estimate its pose and give it to the mapper
        (`steps`: see OnlineMapper.add_frame), after the `touches` riding with it
        (touch_frames.py), unless the pose source does not trust it."""
        self.scorer.log_touches(frame, labels)
        riding = self.overtaken.take(self.mapper.points, touches)
        world_T_object = self.pose_source.estimate(frame, self.mapper)
        if self.pose_source.fuse:
            self.segment.touch_frames += self.overtaken.add(self, riding, frame, world_T_object)
            self.mapper.add_frame(frame, labels, world_T_object=world_T_object, steps=steps)
        else:  # its pose was not tracked: the field learns on, but not from this frame
            self.mapper.optimize(self.mapper.config.steps_per_frame if steps is None else steps)
        self.segment.add_frame(frame.index, frame.time_s)
        self.last_index = frame.index
        for observer in self.observers:
            observer.on_frame(frame, labels, world_T_object, self.mapper)

    def _score(self, frame_index: int, time_s: float) -> dict | None:
        field_T_gt = self.pose_source.field_T_gt_object()
        return self.scorer.score(self.mapper.field, frame_index, time_s, field_T_gt)

    def _checkpoint(self, wait: bool = False) -> None:
        """checkpoint.pt after `self.last_index`, with the segments up to now: the state is
        copied now and written by the writer (`wait`: return once it is on disk)."""
        extra = {
            "scorer": self.scorer.state(),
            "pose": self.pose_source.state(),
            "segments": [s.to_dict() for s in (*self.earlier_segments, self.segment)],
        }
        self.writer.wait()  # one copy of the state in flight at a time
        taken = take_checkpoint(
            self.mapper,
            self.last_index,
            extra,
            self.model_config,
            self.provenance,
            storage=self.settings.checkpoint_storage,
        )
        self.writer.submit(taken)
        if wait:
            self.writer.wait()

    def _snapshot(self, time_s: float, frame_index: int) -> None:
        """Progression snapshots go to disk at once, so a resumed run still has the early ones."""
        field_T_gt = self.pose_source.field_T_gt_object()
        self._write_snapshot(self.mapper.field, field_T_gt, time_s, frame_index)

    def _write_snapshot(self, field, field_T_gt, time_s: float, frame_index: int) -> None:
        maps = self.scorer.snapshot(field, field_T_gt)
        if maps is None:
            return
        write_snapshot(self.snapshots_dir / f"{frame_index:06d}.npz", time_s, maps)

    def _finish(self, baseline: dict) -> dict:
        """Fail on a field that saw no data; final checkpoint, scores and mesh."""
        trained_on = self.mapper.trained_on
        if (
            trained_on["optimizer_steps"] == 0
            or (trained_on["camera_points"] + trained_on["tactile_points"]) == 0
        ):
            if self.failure is not None:
                raise self.failure  # nothing mapped to keep: the producer's error alone
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
        self._checkpoint(wait=True)  # first: a second signal must not lose the frames
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
