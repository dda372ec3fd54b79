"""Allegro CAN protocol bit-exact, and the driver against a fake hand on python-can's virtual bus."""

from __future__ import annotations

import itertools
import struct

import numpy as np
import pytest

from neuralfeels_sem.core.errors import ConfigError, HardwareError
from neuralfeels_sem.sensors.real import allegro_protocol as proto
from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from tests.sensors.real.fake_allegro import FakeAllegro

_channels = itertools.count()
LIMITS = [[-0.5, 1.5]] * 16


def channel() -> str:
    return f"allegro_test_{next(_channels)}"


def test_can_ids_match_the_published_trace() -> None:
    # candump of a real hand: position requests on 0x080..0x08C, torque on 0x180..0x18C.
    assert [proto.can_id(proto.RTR_FINGER_POSE + f) for f in range(4)] == [
        0x080,
        0x084,
        0x088,
        0x08C,
    ]
    assert [proto.can_id(proto.CMD_SET_TORQUE + f) for f in range(4)] == [
        0x180,
        0x184,
        0x188,
        0x18C,
    ]
    assert proto.can_id(proto.CMD_SYSTEM_ON, hand_id=2) == 0x102
    assert proto.split_can_id(0x18E) == (0x63, 2)
    with pytest.raises(ValueError):
        proto.can_id(0x20, hand_id=4)


def test_position_decoding_is_bit_exact() -> None:
    payload = bytes.fromhex("CAFDBDFE90FFCEFF")  # index finger reply from a real hand's trace
    counts = struct.unpack("<4h", payload)
    assert counts == (-566, -323, -112, -50)
    q = proto.decode_positions(payload)
    np.testing.assert_allclose(
        q, np.deg2rad(np.array(counts) * 333.0 / 65536.0), rtol=0, atol=1e-15
    )
    assert proto.encode_positions(q) == payload


def test_torque_encoding_caps_and_round_trips() -> None:
    pwm = proto.torque_to_pwm(np.array([0.1, -0.9, 0.25, 2.0]), torque_limit=0.3)
    assert pwm.tolist() == [120, -360, 300, 360]
    payload = proto.encode_torques(pwm)
    assert payload == struct.pack("<4h", 120, -360, 300, 360)
    assert proto.decode_torques(payload).tolist() == [120, -360, 300, 360]
    with pytest.raises(ValueError):
        proto.encode_torques(np.array([0, 0, 0, 1201]))
    assert proto.encode_period(3) == bytes([3, 0, 0, 0, 0, 0, 0, 0])


def test_driver_reads_all_16_joints_from_a_fake_hand() -> None:
    ch = channel()
    q_true = np.linspace(-0.4, 1.4, 16)
    with FakeAllegro(ch, hand_id=1, q=q_true):
        hand = AllegroCAN(channel=ch, interface="virtual", hand_id=1, timeout_s=0.5)
        hand.open()
        try:
            q = hand.read_joints()
        finally:
            hand.close()
    np.testing.assert_allclose(q, q_true, atol=proto.RAD_PER_COUNT / 2 + 1e-12)


def test_no_hand_on_the_bus_is_one_hardware_line() -> None:
    hand = AllegroCAN(channel=channel(), interface="virtual", timeout_s=0.05)
    with pytest.raises(HardwareError) as info:
        hand.open()
    assert "\n" not in str(info.value) and "sensor.hand" in str(info.value)


def test_commands_are_refused_unless_control_is_enabled() -> None:
    ch = channel()
    with FakeAllegro(ch) as fake:
        hand = AllegroCAN(channel=ch, interface="virtual", timeout_s=0.5)
        hand.open()
        with pytest.raises(ConfigError, match="control=true"):
            hand.send_torques(np.zeros(16))
        hand.close()
    assert fake.torques == [] and proto.CMD_SYSTEM_ON not in fake.commands


def test_position_command_clamps_to_limits_and_caps_torque() -> None:
    ch = channel()
    with FakeAllegro(ch, q=np.zeros(16)) as fake:
        hand = AllegroCAN(
            channel=ch,
            interface="virtual",
            timeout_s=0.5,
            control=True,
            torque_limit=0.2,
            kp=1.0,
            kd=0.0,
            joint_limits=LIMITS,
        )
        hand.open()
        target = np.full(16, 0.05)
        target[0] = 10.0  # far beyond the 1.5 rad limit: clamped, then the torque is capped
        pwm = hand.command_positions(target)
        hand.close()
    assert proto.CMD_SYSTEM_ON in fake.commands
    assert pwm[0] == 240  # min(1.5 * kp, 0.2) * 1200
    assert pwm[1] == 60  # 0.05 * 1200
    sent = {finger: p for finger, p in fake.torques[:4]}
    assert sent[0].tolist() == pwm[:4].tolist()
    assert np.all(np.abs(np.concatenate([p for _, p in fake.torques])) <= 240)


def test_communication_loss_sends_zero_torque_and_latches_estop() -> None:
    ch = channel()
    with FakeAllegro(ch) as fake:
        hand = AllegroCAN(
            channel=ch, interface="virtual", timeout_s=0.05, control=True, joint_limits=LIMITS
        )
        hand.open()
        hand.send_torques(np.full(16, 0.1))
        fake.answering = False
        with pytest.raises(HardwareError, match="emergency stop"):
            for _ in range(10):
                hand.read_joints()
        assert hand.estopped
        with pytest.raises(HardwareError, match="latched"):
            hand.send_torques(np.full(16, 0.1))
        hand.close()
        import time

        time.sleep(0.05)
    last_four = fake.torques[-4:]
    assert sorted(f for f, _ in last_four) == [0, 1, 2, 3]
    assert all(p.tolist() == [0, 0, 0, 0] for _, p in last_four)
