"""sensor=real sub-configs (sensor/hand=...) compose, instantiate cheaply and reject bad values in one line."""

from __future__ import annotations

import pytest
from hydra.utils import instantiate

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.errors import ConfigError
from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from neuralfeels_sem.sensors.real.dynamixel_hand import DynamixelHand
from neuralfeels_sem.sensors.real.real_sensor import RealSensor
from tests.helpers import compose_config


@pytest.mark.parametrize(("hand", "cls"), [("allegro", AllegroCAN), ("dynamixel", DynamixelHand)])
def test_hand_options_build_a_real_sensor(hand: str, cls: type) -> None:
    cfg = compose_config(
        [
            "sensor=real",
            f"sensor/hand={hand}",
            "sensor.digit.fingers=[index]",
            "sensor.digit.serials.index=D20001",
        ]
    )
    validate_config(cfg)
    sensor = instantiate(cfg.sensor)(obj=None, class_names=list(cfg.materials))
    assert isinstance(sensor, RealSensor) and isinstance(sensor.hand, cls)
    assert [c.serial for c in sensor.digits] == ["D20001"]
    assert sensor.object_pose is None  # no markers configured


def test_devices_can_be_switched_off() -> None:
    cfg = compose_config(["sensor=real", "sensor.camera=null", "sensor.hand=null"])
    validate_config(cfg)
    sensor = instantiate(cfg.sensor)()
    assert sensor.camera is None and sensor.hand is None and len(sensor.digits) == 4


def test_markers_config_builds_the_object_pose_estimator() -> None:
    cfg = compose_config(["sensor=real", "+sensor.object_pose.markers.3=[0.03,0,0,0,1.5708,0]"])
    sensor = instantiate(cfg.sensor)()
    assert sorted(sensor.object_pose.object_T_marker) == [3]


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("sensor.digit.fps=45", "QVGA@45"),
        ("sensor.hand.torque_limit=2.0", "torque_limit=2.0"),
        ("sensor.world_T_palm=[0,0,0]", "world_T_palm"),
        ("sensor.digit.fingers=[index,pinky]", "pinky"),
    ],
)
def test_bad_values_are_one_line_config_errors(override: str, message: str) -> None:
    cfg = compose_config(["sensor=real", override])
    with pytest.raises(ConfigError) as info:
        validate_config(cfg)
    assert message in str(info.value) and "\n" not in str(info.value)
