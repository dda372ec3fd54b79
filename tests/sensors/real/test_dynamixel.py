"""Dynamixel hand driver (dynamixel-sdk) against a Protocol 2.0 responder on a pty."""

from __future__ import annotations

import numpy as np
import pytest
from dynamixel_sdk import Protocol2PacketHandler

from neuralfeels_sem.core.errors import ConfigError, HardwareError
from neuralfeels_sem.sensors.real.digit import DigitArray
from neuralfeels_sem.sensors.real.dynamixel_hand import (
    DynamixelHand,
    radians_to_raw,
    raw_to_radians,
)
from neuralfeels_sem.sensors.real.leap_kinematics import LeapKinematics
from neuralfeels_sem.sensors.real.real_sensor import RealSensor
from neuralfeels_sem.sim.kinematics import HandKinematics
from tests.sensors.real.fake_dynamixel import FakeDynamixelChain, crc16, packet
from tests.sensors.real.video_digits import digit_like_frames, write_video

IDS = list(range(10, 26))
BAUD = 1_000_000


def test_crc_matches_the_manual_and_the_sdk() -> None:
    # e-Manual example: PING to ID 1 is FF FF FD 00 01 03 00 01 19 4E.
    assert packet(1, 0x01, b"") == bytes.fromhex("FFFFFD0001030001194E")
    data = bytes(range(200))
    assert crc16(data) == Protocol2PacketHandler().updateCRC(0, list(data), len(data))


def test_angle_conversion_round_trips_and_handles_negative_registers() -> None:
    signs = np.array([1.0, -1.0] * 8)
    raw = np.array([2048, 3072, 1024, 0] * 4)
    q = raw_to_radians(raw, 2048, signs)
    assert q[1] == pytest.approx(-np.pi / 2) and q[2] == pytest.approx(-np.pi / 2)
    np.testing.assert_array_equal(radians_to_raw(q, 2048, signs), raw)
    assert raw_to_radians(np.array([2**32 - 1]), 0, np.ones(1))[0] == pytest.approx(
        -2 * np.pi / 4096
    )


def test_sync_read_returns_the_16_positions() -> None:
    positions = {dxl_id: 2048 + 100 * k - 700 for k, dxl_id in enumerate(IDS)}
    positions[IDS[3]] = -5  # negative multi-turn value
    with FakeDynamixelChain(IDS, positions) as chain:
        hand = DynamixelHand(port=chain.device, baudrate=BAUD, motor_ids=IDS)
        hand.open()
        q = hand.read_joints()
        hand.close()
    expected = (np.array([positions[i] for i in IDS]) - 2048) * 2 * np.pi / 4096
    np.testing.assert_allclose(q, expected, rtol=0, atol=1e-12)
    assert chain.bad_crc_packets == 0


def test_missing_motor_is_one_hardware_line() -> None:
    with FakeDynamixelChain(IDS[:15]) as chain:
        hand = DynamixelHand(port=chain.device, baudrate=BAUD, motor_ids=IDS)
        with pytest.raises(HardwareError) as info:
            hand.open()
    assert f"[{IDS[15]}]" in str(info.value) and "\n" not in str(info.value)


def test_missing_port_names_the_config_key() -> None:
    with pytest.raises(HardwareError, match="sensor.hand.port"):
        DynamixelHand(port="/dev/does_not_exist_dxl").open()


def test_control_clamps_goals_and_loss_disables_torque() -> None:
    limits = [[-0.5, 0.5]] * 16
    with FakeDynamixelChain(IDS) as chain:
        reader = DynamixelHand(port=chain.device, baudrate=BAUD, motor_ids=IDS)
        reader.open()
        with pytest.raises(ConfigError, match="control=true"):
            reader.command_positions(np.zeros(16))
        reader.close()

        hand = DynamixelHand(
            port=chain.device,
            baudrate=BAUD,
            motor_ids=IDS,
            control=True,
            joint_limits=limits,
            timeout_s=0.05,
        )
        hand.open()
        assert chain.registers[(IDS[0], 64)] == b"\x01"  # torque enabled
        assert int.from_bytes(chain.registers[(IDS[0], 38)], "little") == 130  # 350 mA / 2.69
        hand.read_joints()
        target = np.full(16, 0.25)
        target[0] = 3.0
        raw = hand.command_positions(target)
        import time

        time.sleep(0.05)
        assert raw[0] == 2048 + round(0.5 / (2 * np.pi / 4096))
        assert int.from_bytes(chain.registers[(IDS[0], 116)], "little") == raw[0]
        assert int.from_bytes(chain.registers[(IDS[1], 116)], "little") == raw[1]
        chain.answering = False
        with pytest.raises(HardwareError, match="emergency stop"):
            for _ in range(20):
                hand.read_joints()
        assert hand.estopped
        hand.close()
        time.sleep(0.05)
    # Torque-disable writes went out to every motor even though the replies stopped.
    assert all(chain.registers[(i, 64)] == b"\x00" for i in IDS)
    assert chain.bad_crc_packets == 0


def leap_grasp_positions() -> tuple[np.ndarray, dict[int, int]]:
    """A grasp-like LEAP pose and the Present Position each motor reports (motor i on joint i)."""
    q = np.tile([0.1, 0.8, 0.5, 0.3], 4)
    q[12:] = (1.2, 0.2, 0.4, 0.3)
    return q, dict(zip(IDS, radians_to_raw(q, 2048, np.ones(16)).tolist()))


@pytest.mark.parametrize(
    ("kinematics", "model"), [("leap", LeapKinematics), ("allegro", HandKinematics)]
)
def test_real_sensor_digit_poses_are_fk_of_the_configured_hand(
    tmp_path, kinematics: str, model: type
) -> None:
    q_true, positions = leap_grasp_positions()
    videos = {
        f: str(write_video(tmp_path / f"{f}.avi", digit_like_frames(6, seed=k)))
        for k, f in enumerate(("index", "thumb"))
    }
    world_T_palm = [0.1, 0.0, 0.2, 0.0, 1.5708, 0.0]
    with FakeDynamixelChain(IDS, positions) as chain:
        sensor = RealSensor(
            digit=DigitArray(
                serials={}, fingers=["index", "thumb"], video_files=videos, background_frames=1
            ),
            hand=DynamixelHand(
                port=chain.device, baudrate=BAUD, motor_ids=IDS, kinematics=kinematics
            ),
            duration_s=0.1,
            fps=30.0,
            world_T_palm=world_T_palm,
        )
        with sensor:
            frames = list(sensor.frames())
    assert len(frames) == 3 and chain.bad_crc_packets == 0
    q = frames[0].joint_positions
    np.testing.assert_allclose(q, q_true, atol=2 * np.pi / 4096)
    expected = model(world_T_palm=sensor.world_T_palm).sensor_poses(q)
    for finger in ("index", "thumb"):
        np.testing.assert_allclose(
            frames[-1].tactile[finger].world_T_sensor, expected[finger], atol=1e-12
        )
    np.testing.assert_array_equal(sensor.hand.joint_limits, model().joint_limits)


def test_leap_joint_limits_clamp_commands() -> None:
    _, positions = leap_grasp_positions()
    with FakeDynamixelChain(IDS, positions) as chain:
        hand = DynamixelHand(port=chain.device, baudrate=BAUD, motor_ids=IDS, control=True)
        sensor = RealSensor(hand=hand, object_pose=None, duration_s=0.1)
        with sensor:  # open() gives the hand the LEAP URDF limits
            hand.read_joints()
            raw = hand.command_positions(np.full(16, 3.0))
    upper = LeapKinematics().joint_limits[:, 1]
    np.testing.assert_array_equal(raw, radians_to_raw(upper, 2048, np.ones(16)))
    assert raw[1] == 2048 + round(2.23 / (2 * np.pi / 4096))  # MCP forward stops at 2.23 rad
