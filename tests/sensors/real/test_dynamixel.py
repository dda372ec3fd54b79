"""Dynamixel hand driver (dynamixel-sdk) against a Protocol 2.0 responder on a pty."""

from __future__ import annotations

import numpy as np
import pytest
from dynamixel_sdk import Protocol2PacketHandler

from neuralfeels_sem.errors import ConfigError, HardwareError
from neuralfeels_sem.sensors.real.dynamixel_hand import (
    DynamixelHand,
    radians_to_raw,
    raw_to_radians,
)
from tests.sensors.real.fake_dynamixel import FakeDynamixelChain, crc16, packet

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
