"""Smoke tests on a real rig: `pytest -m hardware` with the devices named in environment variables.

    SEMANTICFEELS_DIGIT_SERIAL=D20001 SEMANTICFEELS_CAN_CHANNEL=can0 SEMANTICFEELS_REALSENSE=1 \
    SEMANTICFEELS_DXL_PORT=/dev/ttyUSB0 python -m pytest tests/sensors/real/test_hardware.py -m hardware

Each test skips when its variable is unset, so the file is harmless elsewhere.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from neuralfeels_sem.sensors.real.digit import DigitCamera
from neuralfeels_sem.sensors.real.dynamixel_hand import DynamixelHand
from neuralfeels_sem.sensors.real.realsense import RealSenseCamera

pytestmark = pytest.mark.hardware


def env(name: str) -> str:
    value = os.environ.get(name)
    if not value:
        pytest.skip(f"set {name} to run this hardware test")
    return value


def test_digit_streams_portrait_frames() -> None:
    camera = DigitCamera("index", serial=env("SEMANTICFEELS_DIGIT_SERIAL"), background_frames=5)
    camera.open()
    try:
        frame = camera.read()
    finally:
        camera.close()
    assert frame.shape == (320, 240, 3) and frame.std() > 1.0  # lit gel, not a black frame
    assert camera.background.shape == (320, 240, 3)


def test_allegro_reports_joint_angles_in_range() -> None:
    hand = AllegroCAN(
        channel=env("SEMANTICFEELS_CAN_CHANNEL"),
        interface=os.environ.get("SEMANTICFEELS_CAN_INTERFACE", "socketcan"),
    )
    hand.open()
    try:
        q = hand.read_joints()
    finally:
        hand.close()
    assert q.shape == (16,) and np.all(np.abs(q) < np.pi)


def test_dynamixel_hand_reports_joint_angles() -> None:
    hand = DynamixelHand(port=env("SEMANTICFEELS_DXL_PORT"))
    hand.open()
    try:
        q = hand.read_joints()
    finally:
        hand.close()
    assert q.shape == (16,) and np.all(np.isfinite(q))


def test_realsense_gives_aligned_metric_depth() -> None:
    env("SEMANTICFEELS_REALSENSE")
    camera = RealSenseCamera(world_T_camera=[0.0] * 6)
    camera.open()
    try:
        rgb, depth = camera.read()
    finally:
        camera.close()
    assert rgb.shape[:2] == depth.shape == (camera.intrinsics.height, camera.intrinsics.width)
    valid = depth[depth > 0]
    assert valid.size > 0 and 0.1 < np.median(valid) < 10.0
