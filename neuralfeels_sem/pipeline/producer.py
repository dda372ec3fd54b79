"""The frame producer: acquisition, rendering, contact gating, classification and the
per-frame perception that does not need the field, in a thread ahead of the mapper.

The heavy calls (MuJoCo, pyrender, torch) release the GIL, so the mapper's optimiser
steps run while the next frame is rendered and perceived. With `acquire_thread` the
acquisition (rendering in the simulator, device reads on a rig) runs in a thread of its
own one frame ahead of classification and perception, so the three stages (acquire,
perceive, map) work on three frames side by side where there are cores for them. Frames
reach the mapper through a FrameQueue (pace.py): at sensor.pace=offline every frame, in
order, the producer waiting for room; at realtime at the sensor's clock, the newest frame
replacing an older one the mapper did not take yet. Nothing here reads the field, so the
mapped frames and their labels are those of a sequential loop. An exception in the
producer ends the stream with a StreamEnd carrying it; the mapper's side ends the run
with it.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.pipeline.pace import (
    FrameQueue,
    PaceClock,
    PerceivedFrame,
    StreamEnd,
    in_contact,
)
from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.utils.gl_thread import release_thread_gl
from neuralfeels_sem.utils.thread_priority import at_priority

log = logging.getLogger(__name__)

# Frames perceived ahead of the mapper at sensor.pace=offline: enough to keep it busy while
# the next is rendered, few enough that a stop or a failure wastes little work.
OFFLINE_QUEUE = 2
JOIN_TIMEOUT_S = 30.0  # a producer stuck in a device read is left behind (a daemon)
POLL_S = 0.1  # how often a stage waiting on another looks at the stop flag


class _Acquired:
    """The end of the acquisition stage's frames: the sensor's last one or its error."""

    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error


class FrameProducer:
    """Runs `sensor`'s frames through `classify` and `perceive` in a thread.

    Args:
        sensor: the opened sensor; its `pace` (offline | realtime) sets the queue's policy.
        classify: readings -> one label per tactile reading (the material classifier).
        perceive: frame -> None, the field-free perception kept for the mapper
            (PointExtractor.perceive); `forget` drops it for a frame that will not be mapped.
        after_index: frames up to this index are already mapped (a resumed run).
        acquire_thread: acquire frames in a thread of their own, one frame ahead of
            classification and perception (False: one thread does both in turn).
        nice: added to the threads' nice value (utils/thread_priority.py; 0: as the mapper's).
        touch_frames: realtime: the touches of up to this many frames overtaken before each
            frame made are kept (mapping.overtaken_touch_frames): the sensor makes them
            without their camera reading, they are classified and their contact depths
            inferred, and those with a contact ride with the next frame to the mapper.
    """

    def __init__(
        self,
        sensor: Sensor,
        classify: Callable[[list], list],
        perceive: Callable[[Frame], None],
        forget: Callable[[Frame], None],
        after_index: int = -1,
        acquire_thread: bool = False,
        nice: int = 0,
        touch_frames: int = 0,
    ) -> None:
        self.sensor = sensor
        self.classify = classify
        self.perceive = perceive
        self.realtime = sensor.pace == "realtime"
        self.after_index = after_index
        self.touch_frames = touch_frames if self.realtime else 0
        capacity = 1 if self.realtime else OFFLINE_QUEUE
        self.queue = FrameQueue(
            capacity, self.realtime, on_drop=forget, keep_touches=self.touch_frames > 0
        )
        self.clock: PaceClock | None = None
        self._stop = threading.Event()
        self.cpu_s = 0.0  # the threads' CPU seconds, added as each ends
        # CPU seconds by stage (acquire, classify, perceive), added frame by frame; with the
        # sensor in a process of its own (sensors/process_sensor.py) that process's CPU
        # seconds while streaming are acquire_process, acquire this side's share
        self.stage_cpu_s: dict[str, float] = {}
        self._process_cpu_start: float | None = None
        self._cpu_lock = threading.Lock()
        # acquire -> perceive hand-over: one frame, so acquisition runs one frame ahead
        self._acquired: queue.Queue | None = queue.Queue(maxsize=1) if acquire_thread else None
        self._streaming = threading.Event()  # set when the first frame is perceived
        self._handed_any = False  # the acquisition thread has handed over a frame
        stages = [(self._run, "frame-producer")]
        if acquire_thread:
            stages.append((self._acquire, "frame-acquire"))
        self._threads = [
            threading.Thread(target=at_priority(run, nice), name=name, daemon=True)
            for run, name in stages
        ]

    def start(self) -> None:
        self._process_cpu_start = getattr(self.sensor, "process_cpu_s", None)
        if self.realtime:
            self.clock = PaceClock(float(self.sensor.frame_period_s), self.after_index + 1)
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        """Ask the producer to stop and wait for it (it finishes the frame in hand)."""
        self._stop.set()
        for thread in self._threads:
            thread.join(JOIN_TIMEOUT_S)
            if thread.is_alive():
                log.warning(
                    "%s did not stop within %.0f s; leaving it", thread.name, JOIN_TIMEOUT_S
                )
        if self._process_cpu_start is not None:  # a sensor in a process of its own
            self._add_stage("acquire_process", self.sensor.process_cpu_s - self._process_cpu_start)
            self._process_cpu_start = None

    def _frames(self) -> Iterator[Frame]:
        """The sensor's frames (from the acquisition thread when there is one)."""
        if self._acquired is not None:
            return self._handed_over()
        return self._sensor_frames(self._mapper_ready)

    def _sensor_frames(self, ready: Callable[[], None]) -> Iterator[Frame]:
        if self.clock is not None:
            due = lambda: self._next_due_index(ready)  # noqa: E731
            frames = self.sensor.frames_from_clock(due, self.touch_frames)
        else:
            frames = (f for f in self.sensor.frames() if f.index > self.after_index)
        return self._timed(frames, "acquire")

    def _timed(self, frames: Iterator[Frame], stage: str) -> Iterator[Frame]:
        """`frames`, the CPU time spent making each added to `stage` (a wait for the next
        stage sleeps, so it costs no CPU time)."""
        frames = iter(frames)
        while True:
            cpu_start = time.thread_time()
            frame = next(frames, None)
            self._add_stage(stage, time.thread_time() - cpu_start)
            if frame is None:
                return
            yield frame

    def _add_stage(self, stage: str, seconds: float) -> None:
        with self._cpu_lock:
            self.stage_cpu_s[stage] = self.stage_cpu_s.get(stage, 0.0) + seconds

    def _next_due_index(self, ready: Callable[[], None]) -> int:
        """Realtime: the frame to make next, once the stage after this one is ready for it.

        Perceiving frames the mapper will never take would take the CPU from the mapper
        (on 2 cores); this way the next frame is made while the mapper maps the last one.
        """
        ready()
        return self.clock.due_index()

    def _mapper_ready(self) -> None:
        """Until the mapper has taken the last perceived frame."""
        self.queue.wait_empty(self._stop)

    def _mapper_ready_or_touches(self) -> None:
        """Until the mapper has taken the last perceived frame or a touches-only frame is
        next in the hand-over."""
        while not self._stop.is_set() and self.queue.ready() and not self._touches_next():
            time.sleep(POLL_S / 10)

    def _touches_next(self) -> bool:
        with self._acquired.mutex:  # a look at the head, without taking it
            head = self._acquired.queue[0] if self._acquired.queue else None
        return isinstance(head, Frame) and head.touches_only

    def _perception_ready(self) -> None:
        """Until the perceiving thread has taken the last acquired frame, and the stream's
        clock has started (the first frame perceived: the clock restarts there, so a due
        index asked before would count the models' loading as stream time)."""
        while not self._stop.is_set() and not (
            self._acquired.empty() and (self._streaming.is_set() or not self._handed_any)
        ):
            time.sleep(POLL_S / 10)

    def _acquire(self) -> None:
        """The acquisition thread: the sensor's frames into the hand-over, then its end."""
        cpu_start = time.thread_time()
        end = _Acquired()
        try:
            for frame in self._sensor_frames(self._perception_ready):
                if not self._hand_over(frame):
                    return
                self._handed_any = True
        except BaseException as exc:  # noqa: BLE001 - the perceiving thread ends the stream with it
            end = _Acquired(exc)
        finally:
            self._hand_over(end)
            release_thread_gl()
            self._add_cpu(time.thread_time() - cpu_start)

    def _hand_over(self, item: Frame | _Acquired) -> bool:
        """Put `item` for the perceiving thread, waiting for room; False once stopped."""
        while not self._stop.is_set():
            try:
                self._acquired.put(item, timeout=POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def _handed_over(self) -> Iterator[Frame]:
        """The acquired frames, in order; the acquisition's error is raised here. In
        realtime a frame is taken only once the mapper has taken the last one (a frame made
        for its touches alone, at once)."""
        while not self._stop.is_set():
            if self.clock is not None:
                self._mapper_ready_or_touches()
            try:
                item = self._acquired.get(timeout=POLL_S)
            except queue.Empty:
                continue
            if isinstance(item, _Acquired):
                if item.error is not None:
                    raise item.error
                return
            yield item

    def _add_cpu(self, seconds: float) -> None:
        with self._cpu_lock:
            self.cpu_s += seconds

    def _run(self) -> None:
        cpu_start = time.thread_time()
        try:
            self._produce()
        finally:
            self._add_cpu(time.thread_time() - cpu_start)

    def _produce(self) -> None:
        dropped, expected, first = 0, self.after_index + 1, True
        touches: list[tuple[Frame, dict]] = []  # touches-only frames since the last frame
        try:
            for frame in self._frames():
                if self._stop.is_set():
                    return
                if frame.touches_only:
                    self._keep_touches(frame, touches)
                    continue
                if self.clock is not None:
                    dropped += max(0, frame.index - expected)  # overtaken, never made
                    self._stop.wait(max(0.0, -self.clock.lag(frame.index)))  # until it is due
                expected = frame.index + 1
                labels = self._classify(frame)
                self._perceive(frame)
                if self.clock is not None and first:
                    self.clock.restart()  # the stream starts with its first frame ready
                self._streaming.set()
                first = False
                item = PerceivedFrame(frame, labels, dropped, touches)
                if not self.queue.put(item, self._stop):
                    return
                dropped, touches = 0, []
            self.queue.end(StreamEnd(dropped_before=dropped + self._tail(expected)))
        except BaseException as exc:  # noqa: BLE001 - handed to the mapper's side, which raises it
            self.queue.end(StreamEnd(error=exc))
        finally:
            self.queue.end(StreamEnd())  # a stop: no-op when the stream already ended
            release_thread_gl()

    def _classify(self, frame: Frame) -> dict:
        """finger -> TouchLabel of the frame's tactile readings (CPU time: stage classify)."""
        readings = list(frame.tactile.values())
        cpu_start = time.thread_time()
        labels = (
            {r.finger: lab for r, lab in zip(readings, self.classify(readings))} if readings else {}
        )
        self._add_stage("classify", time.thread_time() - cpu_start)
        return labels

    def _perceive(self, frame: Frame) -> None:
        cpu_start = time.thread_time()
        self.perceive(frame)
        self._add_stage("perceive", time.thread_time() - cpu_start)

    def _keep_touches(self, frame: Frame, touches: list[tuple[Frame, dict]]) -> None:
        """A touches-only frame: classified, and with a contact its depths inferred and
        kept for the next frame; without one it is let go."""
        labels = self._classify(frame)
        if not in_contact(labels):
            return
        self._perceive(frame)
        touches.append((frame, labels))

    def _tail(self, expected: int) -> int:
        """Realtime: the frames after the last one made, overtaken by the end of the stream."""
        total = len(self.sensor)
        return max(0, total - expected) if self.clock is not None and total > 0 else 0
