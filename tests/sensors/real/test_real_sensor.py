"""RealSensor: devices combined into Frames, a device dying mid-run, and all missing devices at once."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from neuralfeels_sem.core.errors import HardwareError
from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from neuralfeels_sem.sensors.real.digit import DigitArray
from neuralfeels_sem.sensors.real.real_sensor import RealSensor
from neuralfeels_sem.sensors.real.realsense import RealSenseCamera
from neuralfeels_sem.sim.kinematics import HandKinematics
from tests.sensors.real.fake_allegro import FakeAllegro
from tests.sensors.real.video_digits import digit_like_frames, write_video


def test_frames_from_videos_and_a_can_hand_survive_a_dying_digit(tmp_path, caplog) -> None:
    videos = {
        "index": str(write_video(tmp_path / "index.avi", digit_like_frames(14, seed=1))),
        "ring": str(
            write_video(tmp_path / "ring.avi", digit_like_frames(6, seed=2))
        ),  # runs out mid-run
    }
    q_true = np.linspace(0.0, 0.6, 16)
    with FakeAllegro("real_sensor_test", q=q_true):
        sensor = RealSensor(
            digit=DigitArray(
                serials={}, fingers=["index", "ring"], video_files=videos, background_frames=2
            ),
            hand=AllegroCAN(channel="real_sensor_test", interface="virtual", timeout_s=0.5),
            duration_s=0.2,
            fps=50.0,
        )
        with caplog.at_level(logging.WARNING), sensor:
            frames = list(sensor.frames())
    assert len(frames) == 10
    assert [("ring" in f.tactile) for f in frames] == [True] * 4 + [False] * 6
    assert all("index" in f.tactile for f in frames)
    warnings = [r for r in caplog.records if "stopped answering" in r.getMessage()]
    assert len(warnings) == 1 and "DIGIT ring" in warnings[0].getMessage()
    expected = HandKinematics(world_T_palm=np.eye(4)).sensor_poses(frames[0].joint_positions)
    np.testing.assert_allclose(frames[0].joint_positions, q_true, atol=1e-4)
    np.testing.assert_array_equal(frames[0].tactile["index"].world_T_sensor, expected["index"])
    assert frames[0].tactile["index"].background.shape == (320, 240, 3)
    assert [f.index for f in frames] == list(range(10))
    assert all(b.time_s > a.time_s for a, b in zip(frames, frames[1:]))
    assert set(sensor.stream_times) == {"hand", "digit/index"}


def test_every_missing_device_is_reported_on_its_own_line() -> None:
    sensor = RealSensor(
        digit=DigitArray(
            serials={"index": "D20001", "thumb": "D20004"}, fingers=["index", "thumb"]
        ),
        camera=RealSenseCamera(world_T_camera=[0.0] * 6),
        hand=AllegroCAN(channel="no_such_can9", interface="socketcan"),
    )
    with pytest.raises(HardwareError) as info:
        sensor.open()
    lines = str(info.value).splitlines()
    assert len(lines) == 4
    assert lines[0].startswith("DIGIT index (serial D20001) not found")
    assert lines[1].startswith("DIGIT thumb (serial D20004) not found")
    assert lines[2].startswith("RealSense front_left") and "sensor.camera" in lines[2]
    assert (
        lines[3].startswith("Allegro hand on socketcan:no_such_can9") and "sensor.hand" in lines[3]
    )


def test_no_device_configured() -> None:
    with pytest.raises(HardwareError, match="no device configured"):
        RealSensor().open()


def test_a_hand_that_stops_answering_leaves_the_digits_running(tmp_path, caplog) -> None:
    video = str(write_video(tmp_path / "thumb.avi", digit_like_frames(12, seed=3)))
    with FakeAllegro("real_sensor_hand_loss", q=np.full(16, 0.2)) as fake:
        sensor = RealSensor(
            digit=DigitArray(
                serials={}, fingers=["thumb"], video_files={"thumb": video}, background_frames=1
            ),
            hand=AllegroCAN(channel="real_sensor_hand_loss", interface="virtual", timeout_s=0.05),
            duration_s=0.3,
            fps=20.0,
        )
        frames = []
        with caplog.at_level(logging.WARNING), sensor:
            for frame in sensor.frames():
                frames.append(frame)
                if len(frames) == 3:
                    fake.answering = False
    assert len(frames) == 6
    assert all(f.joint_positions is not None for f in frames[:3])
    assert all(f.joint_positions is None for f in frames[3:])
    assert all("thumb" in f.tactile for f in frames)
    # DIGIT poses keep the last joint reading once the hand is gone.
    np.testing.assert_array_equal(
        frames[-1].tactile["thumb"].world_T_sensor, frames[2].tactile["thumb"].world_T_sensor
    )
    warnings = [r.getMessage() for r in caplog.records if "stopped answering" in r.getMessage()]
    assert len(warnings) == 1 and "emergency stop" in warnings[0]
