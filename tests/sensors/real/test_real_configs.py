"""sensor=real sub-configs (sensor/hand=...) compose, instantiate cheaply and reject bad values in one line."""

from __future__ import annotations

import numpy as np
import pytest
from hydra.utils import instantiate

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import ConfigError, HardwareError
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from neuralfeels_sem.sensors.real.aruco_pose import MISSING_LAYOUT
from neuralfeels_sem.sensors.real.dynamixel_hand import DynamixelHand
from neuralfeels_sem.sensors.real.real_sensor import RealSensor
from tests.helpers import compose_config, run_cli


@pytest.mark.parametrize(("hand", "cls"), [("allegro", AllegroCAN), ("dynamixel", DynamixelHand)])
def test_hand_options_build_a_real_sensor(hand: str, cls: type) -> None:
    cfg = compose_config(
        [
            "sensor=real",
            f"sensor/hand={hand}",
            "sensor.digit.fingers=[index]",
            "sensor.digit.serials.index=D20001",
            "sensor.object_pose=null",
        ]
    )
    validate_config(cfg)
    sensor = instantiate(cfg.sensor)(obj=None, class_names=list(cfg.materials))
    assert isinstance(sensor, RealSensor) and isinstance(sensor.hand, cls)
    assert [c.serial for c in sensor.digits] == ["D20001"]
    assert sensor.object_pose is None  # the pose stays sensor.world_T_object
    assert sensor.kinematics_name == {"allegro": "allegro", "dynamixel": "leap"}[hand]


def test_the_dynamixel_hand_can_use_the_allegro_like_model() -> None:
    cfg = compose_config(["sensor=real", "sensor/hand=dynamixel", "sensor.hand.kinematics=allegro"])
    validate_config(cfg)
    assert build_sensor(cfg.sensor, None, cfg.materials).kinematics_name == "allegro"


def test_devices_can_be_switched_off() -> None:
    cfg = compose_config(
        ["sensor=real", "sensor.camera=null", "sensor.hand=null", "sensor.object_pose=null"]
    )
    validate_config(cfg)
    sensor = instantiate(cfg.sensor)()
    assert sensor.camera is None and sensor.hand is None and len(sensor.digits) == 4


LAYOUT = [
    "object.aruco.marker_length_m=0.03",
    "object.aruco.markers=[{id:3,pose:[0.03,0,0,0,1.5708,0]},{id:7,pose:[0,0,0.03,0,0,0]}]",
]


def test_the_object_marker_layout_builds_the_object_pose_estimator() -> None:
    cfg = compose_config(["sensor=real", *LAYOUT, "sensor.object_pose.dictionary=DICT_5X5_50"])
    validate_config(cfg)
    sensor = build_sensor(cfg.sensor, None, cfg.materials)
    estimator = sensor.object_pose
    assert sorted(estimator.object_T_marker) == [3, 7]
    assert estimator.marker_length_m == 0.03 and estimator.dictionary_name == "DICT_5X5_50"
    np.testing.assert_allclose(estimator.object_T_marker[7][:3, 3], [0.0, 0.0, 0.03])


@pytest.mark.parametrize("override", [[], ["object=custom", "object.aruco.markers=[]"]])
def test_aruco_source_without_a_layout_names_the_object_key_at_open(override: list[str]) -> None:
    cfg = compose_config(["sensor=real", "sensor.hand=null", "sensor.digit=null", *override])
    validate_config(cfg)
    sensor = build_sensor(cfg.sensor, None, cfg.materials)  # every config instantiates
    with pytest.raises(HardwareError) as info:
        sensor.open()
    lines = str(info.value).splitlines()
    assert lines[0] == MISSING_LAYOUT and len(lines) == 2  # then the missing RealSense
    assert "object.aruco.markers" in lines[0] and "sensor.object_pose=null" in lines[0]


def test_aruco_source_without_a_camera_is_a_config_error() -> None:
    cfg = compose_config(["sensor=real", *LAYOUT, "sensor.camera=null"])
    with pytest.raises(ConfigError, match="needs sensor.camera"):
        build_sensor(cfg.sensor, None, cfg.materials)


def test_cli_without_a_marker_layout_ends_with_the_key_to_set(tmp_path) -> None:
    result = run_cli(
        [
            "task=record",
            "sensor=real",
            "sensor.digit=null",
            "sensor.hand=null",
            f"hydra.run.dir={tmp_path}",
        ]
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    start = result.stderr.index("error: ")
    lines = result.stderr[start + len("error: ") :].strip().splitlines()
    assert lines[0] == MISSING_LAYOUT, result.stderr
    assert len(lines) == 2 and lines[1].startswith("RealSense"), lines


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("sensor.digit.fps=45", "QVGA@45"),
        ("sensor.hand.torque_limit=2.0", "torque_limit=2.0"),
        ("sensor.world_T_palm=[0,0,0]", "world_T_palm"),
        ("sensor.digit.fingers=[index,pinky]", "pinky"),
        ("sensor.object_pose.dictionary=4X4", "OpenCV ArUco dictionary"),
        ("sensor.hand.kinematics=shadow", "sensor.hand.kinematics='shadow' is unknown"),
    ],
)
def test_bad_values_are_one_line_config_errors(override: str, message: str) -> None:
    cfg = compose_config(["sensor=real", override])
    with pytest.raises(ConfigError) as info:
        validate_config(cfg)
    assert message in str(info.value) and "\n" not in str(info.value)
