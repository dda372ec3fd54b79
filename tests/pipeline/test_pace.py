"""The realtime clock, the queue between producer and mapper, and the pace settings."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from neuralfeels_sem.configs.mapping import MappingConfig
from neuralfeels_sem.configs.sensor_real import RealSensorConfig, ReplaySensorConfig
from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.frame import Frame
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


def test_lag_and_drops_add_up_over_segments() -> None:
    first, second = Segment(frames_dropped=3), Segment(frames_dropped=1)
    first.add_lag(0.2)
    first.add_lag(0.4)
    second.add_lag(0.9)
    totals = run_totals([first, second], 0.1)
    assert totals["frames_dropped"] == 4
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


def test_checkpoint_storage_is_one_of_the_codecs() -> None:
    assert MappingConfig(checkpoint_storage="exact").checkpoint_storage == "exact"
    with pytest.raises(ValueError, match="mapping.checkpoint_storage=zip must be one of"):
        MappingConfig(checkpoint_storage="zip")
