"""sensor.advice_lag_frames: at offline pace frame j of an active run is planned with the
advice of frame j - lag exactly, whatever advice came since, so a producer rendering ahead
keeps the run repeatable; lag 1 is the newest advice."""

from __future__ import annotations

import threading
import time

import pytest

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.sensors.sim.sim_sensor import SimSensor


def _sensor(lag: int) -> SimSensor:
    return SimSensor(obj=None, policy="active", advice_lag_frames=lag)


def test_a_frame_takes_the_advice_of_the_frame_lag_before_it() -> None:
    sensor = _sensor(2)
    assert sensor._latest_advice(0) is None and sensor._latest_advice(1) is None
    for k in range(3):
        sensor.advise(k, f"advice {k}")
    assert sensor._latest_advice(3) == "advice 1"  # not the newest, advice 2
    assert sensor._latest_advice(4) == "advice 2"
    assert set(sensor._advices) == {1, 2}  # older ones are no frame's any more


def test_a_frame_rendered_ahead_waits_for_its_advice() -> None:
    sensor = _sensor(3)
    sensor._latest_advice(0)
    got = []
    ahead = threading.Thread(target=lambda: got.append(sensor._latest_advice(4)))
    ahead.start()
    time.sleep(0.2)
    assert not got  # wants frame 1's advice, which has not come
    sensor.advise(0, "advice 0")
    time.sleep(0.1)
    assert not got
    sensor.advise(1, "advice 1")
    ahead.join(timeout=5)
    assert got == ["advice 1"]


def test_a_resumed_run_plans_its_first_frames_without_advice() -> None:
    sensor = _sensor(2)
    assert sensor._latest_advice(50) is None  # the first frame asked for: no advice before it
    assert sensor._latest_advice(51) is None  # frame 49's would never come: no wait
    sensor.advise(50, "advice 50")
    assert sensor._latest_advice(52) == "advice 50"


def test_lag_one_is_the_newest_advice() -> None:
    sensor = _sensor(1)
    sensor.advise(0, "advice 0")
    sensor.advise(1, "advice 1")
    assert sensor._latest_advice(2) == "advice 1"


def test_a_lag_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="advice_lag_frames must be >= 1"):
        _sensor(0)
    with pytest.raises(ValueError, match=r"sensor.advice_lag_frames=0 must be >= 1"):
        SimSensorConfig(advice_lag_frames=0)
