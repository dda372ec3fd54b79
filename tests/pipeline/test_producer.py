"""The frame producer on its own: acquisition in a thread of its own hands over every
frame in order, and a stop frees both of its threads wherever they wait."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from neuralfeels_sem.pipeline.pace import PerceivedFrame, StreamEnd
from neuralfeels_sem.pipeline.producer import FrameProducer


class _Endless:
    """A sensor whose frames never end (until `limit`), each acquired on some thread."""

    pace = "offline"
    frame_period_s = 0.1

    def __init__(self, limit: int | None = None) -> None:
        self.limit = limit
        self.acquired_on: set[str] = set()

    def __len__(self) -> int:
        return -1 if self.limit is None else self.limit

    def frames(self):
        index = 0
        while self.limit is None or index < self.limit:
            self.acquired_on.add(threading.current_thread().name)
            yield SimpleNamespace(index=index, tactile={}, touches_only=False)
            index += 1


def _drain(producer: FrameProducer) -> list:
    items = []
    while not items or not isinstance(items[-1], StreamEnd):
        item = producer.queue.get(timeout=5.0)
        assert item is not None, "the producer stalled"
        items.append(item)
    return items


@pytest.mark.parametrize("acquire", [False, True])
def test_every_frame_reaches_the_queue_in_order(acquire: bool) -> None:
    sensor = _Endless(limit=7)
    perceived_on = set()
    producer = FrameProducer(
        sensor,
        classify=lambda readings: [],
        perceive=lambda frame: perceived_on.add(threading.current_thread().name),
        forget=lambda frame: None,
        after_index=1,
        acquire_thread=acquire,
    )
    producer.start()
    items = _drain(producer)
    producer.stop()
    assert [i.frame.index for i in items if isinstance(i, PerceivedFrame)] == [2, 3, 4, 5, 6]
    assert items[-1].error is None
    assert perceived_on == {"frame-producer"}
    assert sensor.acquired_on == {"frame-acquire" if acquire else "frame-producer"}
    assert producer.cpu_s > 0.0


def test_a_stop_frees_both_threads_wherever_they_wait() -> None:
    producer = FrameProducer(
        _Endless(), lambda r: [], lambda f: None, lambda f: None, acquire_thread=True
    )
    producer.start()
    assert isinstance(producer.queue.get(timeout=5.0), PerceivedFrame)
    # Now the queue is full again and the hand-over holds a frame: both threads wait.
    producer.stop()
    assert not any(t.is_alive() for t in producer._threads)


def test_an_acquisition_error_ends_the_stream_with_it() -> None:
    class _Broken(_Endless):
        def frames(self):
            yield SimpleNamespace(index=0, tactile={}, touches_only=False)
            raise OSError("camera unplugged")

    producer = FrameProducer(
        _Broken(), lambda r: [], lambda f: None, lambda f: None, acquire_thread=True
    )
    producer.start()
    items = _drain(producer)
    producer.stop()
    assert [i.frame.index for i in items[:-1]] == [0]
    assert isinstance(items[-1].error, OSError) and "unplugged" in str(items[-1].error)


class _Streamed(_Endless):
    """A realtime sensor that goes straight to the due frame, as the simulator does; its
    first frame takes `first_s` to make (renderers opening)."""

    pace = "realtime"
    frame_period_s = 0.05

    def __init__(self, limit: int, first_s: float) -> None:
        super().__init__(limit)
        self.first_s = first_s

    def frames_from_clock(self, due_index, touch_frames=0):
        index = 0
        while (index := max(index, due_index())) < len(self):
            if index == 0:
                threading.Event().wait(self.first_s)
            yield SimpleNamespace(index=index, tactile={}, touches_only=False)
            index += 1


def test_realtime_acquisition_waits_for_the_stream_to_start() -> None:
    """The clock restarts when the first frame is ready for the mapper (renderers and models
    loaded): the acquisition thread must not ask for the next due frame before, or that
    set-up would count as stream time and the stream's first second would be skipped."""
    loaded = threading.Event()

    def perceive(frame) -> None:  # the first frame's perception loads the models: 0.3 s
        if not loaded.is_set():
            loaded.set()
            threading.Event().wait(0.3)

    producer = FrameProducer(
        _Streamed(limit=40, first_s=0.5), lambda r: [], perceive, lambda f: None,
        acquire_thread=True,
    )  # fmt: skip
    producer.start()
    first, second = producer.queue.get(timeout=5.0), producer.queue.get(timeout=5.0)
    producer.stop()
    assert first.frame.index == 0
    # due from the restart, not from start(): 0.5 s of the first render and 0.3 s of
    # loading are 16 periods
    assert second.frame.index <= 3, second.frame.index
