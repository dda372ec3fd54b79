"""RealSense pieces that need no camera: intrinsics, depth scale, extrinsics, the missing-device line."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import yaml

from neuralfeels_sem.core.errors import ConfigError, DataError, HardwareError
from neuralfeels_sem.sensors.real.realsense import (
    RealSenseCamera,
    depth_to_metres,
    intrinsics_from_rs,
    load_world_T_camera,
)


def test_intrinsics_from_a_pyrealsense2_object() -> None:
    rs = pytest.importorskip("pyrealsense2")  # not installed where PyPI has no wheel (setup.py)
    intr = rs.intrinsics()
    intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = (
        640,
        480,
        615.2,
        615.9,
        321.4,
        238.7,
    )
    ours = intrinsics_from_rs(intr)
    assert (ours.width, ours.height) == (640, 480)
    assert ours.fx == pytest.approx(615.2) and ours.cy == pytest.approx(238.7)


def test_depth_units_to_metres() -> None:
    raw = np.array([[0, 1000, 65535]], dtype=np.uint16)
    depth = depth_to_metres(raw, 0.001)
    assert depth.dtype == np.float32
    np.testing.assert_allclose(depth, [[0.0, 1.0, 65.535]], rtol=1e-6)
    with pytest.raises(ValueError):
        depth_to_metres(raw.astype(np.int32), 0.001)


def test_extrinsics_from_calibration_or_config(tmp_path) -> None:
    pose = np.eye(4)
    pose[:3, 3] = [0.1, 0.2, 0.3]
    path = tmp_path / "cal.yaml"
    path.write_text(yaml.safe_dump({"world_T_camera": pose.tolist()}))
    np.testing.assert_array_equal(load_world_T_camera(path), pose)
    assert RealSenseCamera(calibration_file=str(path))._extrinsics()[0, 3] == 0.1
    assert RealSenseCamera(world_T_camera=[0, 0, 0.5, 0, 0, 0])._extrinsics()[2, 3] == 0.5
    with pytest.raises(ConfigError, match="task=calibrate"):
        RealSenseCamera()._extrinsics()
    with pytest.raises(DataError):
        load_world_T_camera(tmp_path / "missing.yaml")


def test_no_camera_connected_is_one_line() -> None:
    rs = pytest.importorskip("pyrealsense2")
    if len(rs.context().query_devices()) > 0:
        pytest.skip("a RealSense is connected")
    with pytest.raises(HardwareError) as info:
        RealSenseCamera().open()
    assert (
        "not found" in str(info.value)
        and "sensor.camera" in str(info.value)
        and "\n" not in str(info.value)
    )


def test_no_pyrealsense2_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)  # what an Arm board without it sees
    with pytest.raises(HardwareError) as info:
        RealSenseCamera().open()
    message = str(info.value)
    assert "pyrealsense2 is not installed" in message and "sensor.camera=null" in message
    assert "\n" not in message
