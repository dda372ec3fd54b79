"""The realtime clock, the queue between producer and mapper, and the pace settings."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest

from neuralfeels_sem.configs.mapping import MappingConfig
from neuralfeels_sem.configs.sensor_real import RealSensorConfig, ReplaySensorConfig
from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_INTRINSICS, DIGIT_WIDTH
from neuralfeels_sem.core.frame import Frame, TactileReading
from neuralfeels_sem.pipeline.pace import FrameQueue, PaceClock, PerceivedFrame, StreamEnd
from neuralfeels_sem.pipeline.segments import Segment, load_segments, run_totals
from neuralfeels_sem.sensors.base import Sensor


def _frame(index: int) -> Frame:
    return Frame(index=index, time_s=index * 0.1, world_T_object=np.eye(4))


def test_offline_queue_keeps_every_frame_in_order() -> None:
    queue, stop = FrameQueue(2, keep_newest=False), threading.Event()

    def produce() -> None:
        for i in range(5):
            queue.put(PerceivedFrame(_frame(i), {}), stop)
        queue.end(StreamEnd())

    thread = threading.Thread(target=produce)
    thread.start()
    got = []
    while not isinstance(item := queue.get(1.0), StreamEnd):
        got.append(item.frame.index)
    thread.join()
    assert got == [0, 1, 2, 3, 4]


def test_realtime_queue_keeps_the_newest_and_carries_the_drop_count() -> None:
    forgotten = []
    queue = FrameQueue(1, keep_newest=True, on_drop=lambda f: forgotten.append(f.index))
    stop = threading.Event()
    queue.put(PerceivedFrame(_frame(0), {}, dropped_before=2), stop)
    queue.put(PerceivedFrame(_frame(1), {}), stop)
    queue.put(PerceivedFrame(_frame(2), {}), stop)
    item = queue.get(0.0)
    assert item.frame.index == 2 and item.dropped_before == 2 + 1 + 1
    assert forgotten == [0, 1] and queue.get(0.0) is None


def test_a_stop_frees_a_producer_waiting_for_room() -> None:
    queue, stop = FrameQueue(1, keep_newest=False), threading.Event()
    queue.put(PerceivedFrame(_frame(0), {}), stop)
    threading.Timer(0.2, stop.set).start()
    assert queue.put(PerceivedFrame(_frame(1), {}), stop) is False


def test_the_clock_counts_from_the_first_frame_of_the_segment() -> None:
    clock = PaceClock(0.1, first_index=7)
    assert clock.due_index() == 7
    assert clock.due_at(9) == pytest.approx(clock.start + 0.2)
    time.sleep(0.25)
    assert clock.due_index() == 9 and clock.lag(7) >= 0.25


class _Counting(Sensor):
    def frames(self):
        for i in range(6):
            yield _frame(i)


def test_frames_from_clock_skips_the_overtaken_frames() -> None:
    due = iter([0, 0, 3, 3, 5, 5, 5])
    got = [f.index for f in _Counting().frames_from_clock(lambda: next(due))]
    assert got == [0, 1, 3, 5]


class _Touching(Sensor):
    """Six frames with a camera; the even ones with a DIGIT reading too."""

    def frames(self):
        for i in range(6):
            reading = TactileReading(
                finger="index",
                image=np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH, 3), np.uint8),
                world_T_sensor=np.eye(4),
                intrinsics=DIGIT_INTRINSICS,
            )
            camera = SimpleNamespace(name="front_left")
            tactile = {"index": reading} if i % 2 == 0 else {}
            yield Frame(i, i * 0.1, np.eye(4), tactile=tactile, camera=camera)


def test_frames_from_clock_keeps_the_last_overtaken_frames_with_a_digit_reading() -> None:
    """Due 5 from frame 0 on: frames 0-4 are overtaken; of the last three (2-4) those with
    a DIGIT reading (2, 4) come as touches-only frames, without their camera reading."""
    got = list(_Touching().frames_from_clock(lambda: 5, touch_frames=3))
    assert [(f.index, f.touches_only) for f in got] == [(2, True), (4, True), (5, False)]
    assert [f.camera is None for f in got] == [True, True, False]


def _contact(touched: bool) -> dict:
    return {"index": SimpleNamespace(contact=touched)}


def test_realtime_queue_carries_the_touches_of_the_frames_it_lets_go() -> None:
    """With keep_touches a frame let go travels with the newer one when it touched (and so
    do the touches it carried); one without a touch is forgotten."""
    forgotten, stop = [], threading.Event()
    queue = FrameQueue(1, True, on_drop=lambda f: forgotten.append(f.index), keep_touches=True)
    earlier = (_frame(0), _contact(True))
    queue.put(PerceivedFrame(_frame(1), _contact(True), touches=[earlier]), stop)
    queue.put(PerceivedFrame(_frame(2), _contact(False)), stop)
    queue.put(PerceivedFrame(_frame(3), {}), stop)
    item = queue.get(0.0)
    assert [f.index for f, _ in item.touches] == [0, 1]
    assert forgotten == [2] and item.dropped_before == 2
    plain = FrameQueue(1, True, on_drop=lambda f: forgotten.append(f.index))
    plain.put(PerceivedFrame(_frame(4), _contact(True)), stop)
    plain.put(PerceivedFrame(_frame(5), {}), stop)
    assert plain.get(0.0).touches == [] and forgotten == [2, 4]


def test_lag_and_drops_add_up_over_segments() -> None:
    first, second = Segment(frames_dropped=3), Segment(frames_dropped=1)
    first.add_lag(0.2)
    first.add_lag(0.4)
    second.add_lag(0.9)
    first.touch_frames, second.touch_frames = 2, 1
    totals = run_totals([first, second], 0.1)
    assert totals["frames_dropped"] == 4 and totals["touch_frames"] == 3
    assert totals["lag_max_s"] == 0.9 and totals["lag_mean_s"] == pytest.approx(0.5)
    assert run_totals([Segment()], 0.1)["lag_max_s"] is None


def test_thread_cpu_adds_up_over_segments() -> None:
    first = Segment(mapper_cpu_s=1.0)
    first.record_producer(2.0, {"acquire": 0.5, "classify": 1.0})
    second = Segment(mapper_cpu_s=3.0)
    second.record_producer(0.5, {"classify": 0.25, "perceive": 0.125})
    totals = run_totals([first, second], 0.1)
    assert totals["producer_cpu_s"] == 2.5 and totals["mapper_cpu_s"] == 4.0
    assert totals["producer_stage_cpu_s"] == {"acquire": 0.5, "classify": 1.25, "perceive": 0.125}
    # A checkpoint written before these fields existed still loads (zeros, no stages).
    old = {k: v for k, v in Segment().to_dict().items() if "_cpu_s" not in k}
    assert load_segments([old])[0].producer_cpu_s == 0.0
    assert load_segments([old])[0].producer_stage_cpu_s == {}


def test_pace_defaults_and_range_checks() -> None:
    assert SimSensorConfig().pace == "offline" and ReplaySensorConfig().pace == "offline"
    assert RealSensorConfig().pace == "realtime"
    for schema in (SimSensorConfig, RealSensorConfig, ReplaySensorConfig):
        with pytest.raises(ValueError, match="sensor.pace='fast': use one of offline, realtime"):
            schema(pace="fast")
    for bad in (0.0, -1.0):
        with pytest.raises(ValueError, match="mapping.max_lag_s"):
            MappingConfig(max_lag_s=bad)
    with pytest.raises(ValueError, match="mapping.overtaken_touch_frames=-1 must be >= 0"):
        MappingConfig(overtaken_touch_frames=-1)


def test_checkpoint_storage_is_one_of_the_codecs() -> None:
    assert MappingConfig(checkpoint_storage="exact").checkpoint_storage == "exact"
    with pytest.raises(ValueError, match="mapping.checkpoint_storage=zip must be one of"):
        MappingConfig(checkpoint_storage="zip")
