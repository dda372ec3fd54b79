"""The frame producer: acquisition, rendering, contact gating, classification and the
per-frame perception that does not need the field, in a thread ahead of the mapper.

The heavy calls (MuJoCo, pyrender, torch) release the GIL, so the mapper's optimiser
steps run while the next frame is rendered and perceived. Frames reach the mapper through
a FrameQueue (pace.py): at sensor.pace=offline every frame, in order, the producer waiting
for room; at realtime at the sensor's clock, the newest frame replacing an older one the
mapper did not take yet. Nothing here reads the field, so the mapped frames and their
labels are those of a sequential loop. An exception in the producer ends the stream with a
StreamEnd carrying it; the mapper's side ends the run with it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.pipeline.pace import FrameQueue, PaceClock, PerceivedFrame, StreamEnd
from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.utils.gl_thread import release_thread_gl

log = logging.getLogger(__name__)

# Frames perceived ahead of the mapper at sensor.pace=offline: enough to keep it busy while
# the next is rendered, few enough that a stop or a failure wastes little work.
OFFLINE_QUEUE = 2
JOIN_TIMEOUT_S = 30.0  # a producer stuck in a device read is left behind (a daemon)


class FrameProducer:
    """Runs `sensor`'s frames through `classify` and `perceive` in a thread.

    Args:
        sensor: the opened sensor; its `pace` (offline | realtime) sets the queue's policy.
        classify: readings -> one label per tactile reading (the material classifier).
        perceive: frame -> None, the field-free perception kept for the mapper
            (PointExtractor.perceive); `forget` drops it for a frame that will not be mapped.
        after_index: frames up to this index are already mapped (a resumed run).
    """

    def __init__(
        self,
        sensor: Sensor,
        classify: Callable[[list], list],
        perceive: Callable[[Frame], None],
        forget: Callable[[Frame], None],
        after_index: int = -1,
    ) -> None:
        self.sensor = sensor
        self.classify = classify
        self.perceive = perceive
        self.realtime = sensor.pace == "realtime"
        self.after_index = after_index
        capacity = 1 if self.realtime else OFFLINE_QUEUE
        self.queue = FrameQueue(capacity, keep_newest=self.realtime, on_drop=forget)
        self.clock: PaceClock | None = None
        self._stop = threading.Event()
        self.cpu_s = 0.0  # the thread's CPU seconds, set when it ends
        self._thread = threading.Thread(target=self._run, name="frame-producer", daemon=True)

    def start(self) -> None:
        if self.realtime:
            self.clock = PaceClock(float(self.sensor.frame_period_s), self.after_index + 1)
        self._thread.start()

    def stop(self) -> None:
        """Ask the producer to stop and wait for it (it finishes the frame in hand)."""
        self._stop.set()
        self._thread.join(JOIN_TIMEOUT_S)
        if self._thread.is_alive():
            log.warning("the frame producer did not stop within %.0f s; leaving it", JOIN_TIMEOUT_S)

    def _frames(self) -> Iterator[Frame]:
        if self.clock is not None:
            return self.sensor.frames_from_clock(self._next_due_index)
        return (f for f in self.sensor.frames() if f.index > self.after_index)

    def _next_due_index(self) -> int:
        """Realtime: the frame to make next, once the mapper has taken the last one.

        Perceiving frames the mapper will never take would take the CPU from the mapper
        (on 2 cores); this way the next frame is made while the mapper maps the last one.
        """
        self.queue.wait_empty(self._stop)
        return self.clock.due_index()

    def _run(self) -> None:
        cpu_start = time.thread_time()
        try:
            self._produce()
        finally:
            self.cpu_s = time.thread_time() - cpu_start

    def _produce(self) -> None:
        dropped, expected, first = 0, self.after_index + 1, True
        try:
            for frame in self._frames():
                if self._stop.is_set():
                    return
                if self.clock is not None:
                    dropped += max(0, frame.index - expected)  # overtaken, never made
                    self._stop.wait(max(0.0, -self.clock.lag(frame.index)))  # until it is due
                expected = frame.index + 1
                readings = list(frame.tactile.values())
                labels = (
                    {r.finger: lab for r, lab in zip(readings, self.classify(readings))}
                    if readings
                    else {}
                )
                self.perceive(frame)
                if self.clock is not None and first:
                    self.clock.restart()  # the stream starts with its first frame ready
                first = False
                if not self.queue.put(PerceivedFrame(frame, labels, dropped), self._stop):
                    return
                dropped = 0
            self.queue.end(StreamEnd(dropped_before=dropped + self._tail(expected)))
        except BaseException as exc:  # noqa: BLE001 - handed to the mapper's side, which raises it
            self.queue.end(StreamEnd(error=exc))
        finally:
            self.queue.end(StreamEnd())  # a stop: no-op when the stream already ended
            release_thread_gl()

    def _tail(self, expected: int) -> int:
        """Realtime: the frames after the last one made, overtaken by the end of the stream."""
        total = len(self.sensor)
        return max(0, total - expected) if self.clock is not None and total > 0 else 0
