"""Allegro Hand V4 CAN protocol (SimLab / Wonik), as pure encode/decode functions.

Every frame uses an 11-bit standard id `(command << 2) | hand_id` (hand_id 0..3 lets
several hands share a bus). Commands used here:

- 0x20 + f  position request (RTR) for finger f; the hand answers with the same id and
  8 bytes: four little-endian int16 joint positions, 1 count = 333/65536 degree.
- 0x60 + f  set torque for finger f: four little-endian int16 PWM values in -1200..1200.
- 0x40 / 0x41  servo (system) on / off, no payload.
- 0x81  periodic broadcast periods (4 x uint16 ms: position, IMU, temperature, status); 0 = off.

Fingers are index, middle, ring, thumb (f = 0..3); joint j of finger f is entry 4 f + j
of the 16-vector, the Allegro order used everywhere in this project.
"""

from __future__ import annotations

import struct

import numpy as np

CMD_SYSTEM_ON = 0x40
CMD_SYSTEM_OFF = 0x41
CMD_SET_TORQUE = 0x60
CMD_SET_PERIOD = 0x81
RTR_FINGER_POSE = 0x20

NUM_FINGERS = 4
JOINTS_PER_FINGER = 4
NUM_JOINTS = NUM_FINGERS * JOINTS_PER_FINGER
# One encoder count in radians (the firmware reports 333/65536 degree per count).
RAD_PER_COUNT = np.deg2rad(333.0 / 65536.0)
PWM_LIMIT = 1200  # firmware's torque command range (PWM duty counts)


def can_id(command: int, hand_id: int = 0) -> int:
    """11-bit CAN arbitration id of an Allegro command for hand `hand_id`."""
    if not 0 <= hand_id <= 3:
        raise ValueError(f"hand_id={hand_id} must be in 0..3")
    if not 0 <= command <= 0x1FF:
        raise ValueError(f"command {command:#x} does not fit the 9 command bits")
    return (command << 2) | hand_id


def split_can_id(arbitration_id: int) -> tuple[int, int]:
    """Inverse of `can_id`: (command, hand_id)."""
    return arbitration_id >> 2, arbitration_id & 0x3


def encode_positions(q_finger: np.ndarray) -> bytes:
    """Four joint angles (rad) of one finger -> the 8-byte position reply payload."""
    q = np.asarray(q_finger, dtype=np.float64)
    if q.shape != (JOINTS_PER_FINGER,):
        raise ValueError(f"one finger has 4 joints, got shape {q.shape}")
    counts = np.clip(np.round(q / RAD_PER_COUNT), -32768, 32767).astype(np.int64)
    return struct.pack("<4h", *counts.tolist())


def decode_positions(payload: bytes) -> np.ndarray:
    """8-byte position reply payload -> four joint angles (rad)."""
    if len(payload) != 8:
        raise ValueError(f"position payload must be 8 bytes, got {len(payload)}")
    return np.asarray(struct.unpack("<4h", bytes(payload)), dtype=np.float64) * RAD_PER_COUNT


def torque_to_pwm(torque: np.ndarray, torque_limit: float) -> np.ndarray:
    """Normalised torques -> int16 PWM counts, clipped to +-torque_limit (a fraction of full scale).

    `torque` is in units of full scale (1.0 = the firmware's 1200 PWM counts). The cap
    protects the hand and the sensors from a runaway controller.
    """
    if not 0.0 <= torque_limit <= 1.0:
        raise ValueError(f"torque_limit={torque_limit} must be in [0, 1]")
    t = np.clip(np.asarray(torque, dtype=np.float64), -torque_limit, torque_limit)
    return np.round(t * PWM_LIMIT).astype(np.int64)


def encode_torques(pwm_finger: np.ndarray) -> bytes:
    """Four PWM counts of one finger -> the 8-byte set-torque payload."""
    pwm = np.asarray(pwm_finger)
    if pwm.shape != (JOINTS_PER_FINGER,):
        raise ValueError(f"one finger has 4 joints, got shape {pwm.shape}")
    if np.any(np.abs(pwm) > PWM_LIMIT):
        raise ValueError(f"PWM values {pwm.tolist()} exceed +-{PWM_LIMIT}")
    return struct.pack("<4h", *[int(v) for v in pwm])


def decode_torques(payload: bytes) -> np.ndarray:
    """8-byte set-torque payload -> four PWM counts (int)."""
    if len(payload) != 8:
        raise ValueError(f"torque payload must be 8 bytes, got {len(payload)}")
    return np.asarray(struct.unpack("<4h", bytes(payload)), dtype=np.int64)


def encode_period(
    position_ms: int, imu_ms: int = 0, temperature_ms: int = 0, status_ms: int = 0
) -> bytes:
    """Payload of CMD_SET_PERIOD: the hand's broadcast periods in ms (0 turns one off)."""
    return struct.pack("<4H", position_ms, imu_ms, temperature_ms, status_ms)
