"""A sensor in a process of its own (mapping.acquire_process): the same frames as inline,
the child's errors raised with their type, a dead child named, advice delivered while a
frame waits for it, and the producer counting the child's CPU time."""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import threading

import numpy as np
import pytest
from omegaconf import OmegaConf

from neuralfeels_sem.core.errors import FrameSourceError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.pipeline.pace import PerceivedFrame, StreamEnd
from neuralfeels_sem.pipeline.producer import FrameProducer
from neuralfeels_sem.sensors.base import IndexedSensor, Sensor
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.sensors.process_sensor import ProcessSensor
from neuralfeels_sem.utils.paths import REPO_DIR


class _Counter(IndexedSensor):
    """Frames whose pose says their index; `fail_at` raises there, `die_at` kills the
    process; with `lockstep` frame j waits for the advice of frame j - 1 (as the sim)."""

    frame_period_s = 0.05

    def __init__(self, length=5, fail_at=None, die_at=None, lockstep=False) -> None:
        self.length, self.fail_at, self.die_at = length, fail_at, die_at
        self.lockstep = lockstep
        self.advised = threading.Condition()
        self.advice: list = []

    def __len__(self) -> int:
        return self.length

    @property
    def accepts_advice(self) -> bool:
        return self.lockstep

    def advise(self, frame_index: int, advice) -> None:
        with self.advised:
            self.advice.append((frame_index, advice))
            self.advised.notify_all()

    def touch_plan(self) -> dict:
        return {"advice": list(self.advice)}

    def frame_at(self, index: int, touches_only: bool = False) -> Frame:
        if index == self.fail_at:
            raise ValueError(f"frame {index} is broken")
        if index == self.die_at:
            os._exit(3)
        if self.lockstep and index > 0:
            with self.advised:
                assert self.advised.wait_for(lambda: self.advice, timeout=10.0)
        pose = np.eye(4)
        pose[0, 3] = index
        return Frame(index=index, time_s=index * self.frame_period_s, world_T_object=pose,
                     touches_only=touches_only)  # fmt: skip


def _in_process(**kwargs) -> ProcessSensor:
    return ProcessSensor(functools.partial(_Counter, **kwargs))


def test_frames_come_from_the_child_in_order_with_its_clock() -> None:
    with _in_process(length=4) as sensor:
        assert len(sensor) == 4 and sensor.frame_period_s == 0.05
        poses = [f.world_T_object[0, 3] for f in sensor.frames()]
        assert poses == [0, 1, 2, 3]
        assert sensor.process_cpu_s > 0.0
    assert sensor._process is None  # closed


def test_realtime_goes_straight_to_the_due_frame() -> None:
    due = iter([1, 3, 3, 7])
    with _in_process(length=6) as sensor:
        got = [(f.index, f.touches_only) for f in sensor.frames_from_clock(lambda: next(due), 1)]
    assert got == [(1, False), (2, True), (3, False), (4, False)]


def test_an_error_in_the_child_is_raised_with_its_type() -> None:
    with _in_process(fail_at=2) as sensor:
        sensor.frame_at(1)
        with pytest.raises(ValueError, match="frame 2 is broken") as caught:
            sensor.frame_at(2)
        assert sensor.frame_at(3).index == 3  # the child goes on serving
    if hasattr(caught.value, "__notes__"):  # the child's traceback, as a note
        assert "in the sensor's process" in caught.value.__notes__[0]


def test_a_child_that_dies_is_named() -> None:
    with _in_process(die_at=1) as sensor, pytest.raises(FrameSourceError, match="exit code 3"):
        sensor.frame_at(1)


def test_a_sensor_that_fails_to_build_fails_the_open() -> None:
    sensor = ProcessSensor(functools.partial(_Counter, length="many", fail_at=None))
    with pytest.raises(TypeError):
        with sensor:
            len(sensor)
        raise AssertionError("opened")


def test_advice_reaches_a_frame_that_waits_for_it() -> None:
    """Frame 1 waits in the child for frame 0's advice: sent while that call is in flight,
    it must not queue behind it."""
    with _in_process(lockstep=True) as sensor:
        assert sensor.accepts_advice
        got = []
        waiting = threading.Thread(target=lambda: got.append(sensor.frame_at(1)))
        waiting.start()
        # The session reads the plan on the thread that advises: it must not queue behind
        # the waiting frame (that deadlocked an active run).
        plans = []
        reader = threading.Thread(target=lambda: plans.append(sensor.touch_plan()))
        reader.start()
        reader.join(5.0)
        assert plans == [{"advice": []}], plans  # as of the child's last reply
        sensor.advise(0, "press here")
        waiting.join(20.0)
        assert got and got[0].index == 1
        assert sensor.touch_plan() == {"advice": [(0, "press here")]}  # with frame 1's reply


def test_the_producer_counts_the_childs_cpu_time() -> None:
    with _in_process(length=6) as sensor:
        producer = FrameProducer(sensor, lambda r: [], lambda f: None, lambda f: None,
                                 after_index=1, acquire_thread=True)  # fmt: skip
        producer.start()
        items = []
        while not items or not isinstance(items[-1], StreamEnd):
            items.append(producer.queue.get(timeout=10.0))
        producer.stop()
    assert [i.frame.index for i in items if isinstance(i, PerceivedFrame)] == [2, 3, 4, 5]
    assert producer.stage_cpu_s["acquire_process"] > 0.0


def test_only_a_sensor_that_makes_frames_by_index_moves() -> None:
    replay = OmegaConf.create({"_target_": "tests.sensors.test_process_sensor._Streaming",
                               "name": "replay"})  # fmt: skip
    assert isinstance(build_sensor(replay, None, ["plastic"], own_process=True), _Streaming)
    counter = OmegaConf.create({"_target_": "tests.sensors.test_process_sensor._Counter"})
    assert isinstance(build_sensor(counter, None, ["plastic"], own_process=True), ProcessSensor)
    assert isinstance(build_sensor(counter, None, ["plastic"]), _Counter)


class _Streaming(Sensor):
    """Stands in for a streaming sensor (a rig, a replay): frames, but none by index."""

    def __init__(self, name: str) -> None:
        self.name = name

    def frames(self):
        return iter(())


def test_the_simulator_in_a_process_makes_the_same_frames() -> None:
    from neuralfeels_sem.sensors.sim import SimSensor
    from tests.sim.shapes import CLASSES, two_material_sphere

    make = functools.partial(
        SimSensor, two_material_sphere(), class_names=CLASSES, duration_s=0.3, seed=0
    )
    with make() as inline, ProcessSensor(make) as moved:
        assert len(moved) == len(inline) == 3
        np.testing.assert_array_equal(moved.hand_model().world_T_palm,
                                      inline.hand_model().world_T_palm)  # fmt: skip
        for a, b in zip(inline.frames(), moved.frames(), strict=True):
            np.testing.assert_array_equal(a.world_T_object, b.world_T_object)
            np.testing.assert_array_equal(a.camera.depth, b.camera.depth)
            for finger, reading in a.tactile.items():
                np.testing.assert_array_equal(reading.image, b.tactile[finger].image)


def test_a_program_that_leaves_the_sensor_open_still_exits() -> None:
    """multiprocessing's exit hook would wait for ever for a child that ignores SIGTERM: the
    sensor closes itself at exit, ahead of that hook."""
    script = (
        "from tests.sensors.test_process_sensor import _in_process\n"
        "if __name__ == '__main__':\n"
        "    sensor = _in_process()\n"
        "    sensor.open()\n"
        "    print(sensor.frame_at(2).index)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], cwd=REPO_DIR, capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0 and done.stdout.strip() == "2", done.stderr


def _indices_in_a_worker(length: int) -> list[int]:
    with _in_process(length=length) as sensor:
        return [f.index for f in sensor.frames()]


def test_a_sweep_worker_runs_the_sensor_in_a_process() -> None:
    """hydra's joblib launcher runs each job of a sweep in a loky worker, where
    multiprocessing's spawn could not start a child (it copied the worker's start method)."""
    from joblib import Parallel, delayed

    got = Parallel(n_jobs=2, backend="loky")(delayed(_indices_in_a_worker)(n) for n in (2, 3))
    assert got == [[0, 1], [0, 1, 2]]
