"""A Dynamixel-driven 16-joint hand (LEAP-style) over dynamixel-sdk, Protocol 2.0.

Positions come from one group sync read of Present Position (X-series control table:
address 132, 4 bytes) for the configured motor IDs, listed in the kinematic model's joint
order (index 0-3, middle 4-7, ring 8-11, thumb 12-15; LEAP: motor i on URDF joint i).
Angle = sign * (raw - zero_raw) * 2 pi / 4096; a LEAP Hand reads 2048 (pi) at its URDF zero.

Commands (Goal Position, address 116, group sync write) are refused unless
`control=True`; goals are clamped to the joint limits; the torque cap is written once as
the motors' Current Limit (address 38) at open; on communication loss for `timeout_s`
the driver disables torque on every motor, latches an emergency stop and raises.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.errors import ConfigError, HardwareError

log = logging.getLogger(__name__)

ADDR_TORQUE_ENABLE = 64
ADDR_CURRENT_LIMIT = 38
ADDR_GOAL_POSITION = 116
ADDR_PRESENT_POSITION = 132
POSITION_BYTES = 4
COUNTS_PER_REV = 4096
RAD_PER_COUNT = 2.0 * np.pi / COUNTS_PER_REV


def raw_to_radians(raw: np.ndarray, zero_raw: int, signs: np.ndarray) -> np.ndarray:
    """Present Position counts (signed 32-bit) -> joint angles in rad."""
    raw = np.asarray(raw, dtype=np.int64)
    raw = np.where(raw >= 2**31, raw - 2**32, raw)  # the register is a signed 32-bit value
    return signs * (raw - zero_raw) * RAD_PER_COUNT


def radians_to_raw(q: np.ndarray, zero_raw: int, signs: np.ndarray) -> np.ndarray:
    """Inverse of `raw_to_radians` (rounded to whole counts)."""
    return np.round(np.asarray(q) / (signs * RAD_PER_COUNT) + zero_raw).astype(np.int64)


PING_ATTEMPTS = 3  # pings per motor before it counts as missing


class DynamixelHand:
    """16 Dynamixel X-series motors on one serial port (U2D2 or similar)."""

    def __init__(
        self,
        port: str = "/dev/ttyUSB0",
        baudrate: int = 4_000_000,
        motor_ids: Sequence[int] = tuple(range(16)),
        zero_raw: int = 2048,
        signs: Sequence[float] | None = None,
        timeout_s: float = 0.2,
        control: bool = False,
        current_limit_ma: float = 350.0,
        joint_limits: Sequence[Sequence[float]] | None = None,
        kinematics: str = "leap",
    ) -> None:
        if len(motor_ids) != 16 or len(set(motor_ids)) != 16:
            raise ValueError(f"motor_ids must be 16 distinct ids, got {list(motor_ids)}")
        self.port = port
        self.baudrate = baudrate
        self.motor_ids = [int(i) for i in motor_ids]
        self.zero_raw = zero_raw
        self.signs = np.ones(16) if signs is None else np.asarray(signs, dtype=np.float64)
        if self.signs.shape != (16,):
            raise ValueError(f"signs must have 16 entries, got {self.signs.shape}")
        self.timeout_s = timeout_s
        self.control = control
        self.current_limit_ma = current_limit_ma
        self.joint_limits = (
            None if joint_limits is None else np.asarray(joint_limits, dtype=np.float64)
        )
        self.kinematics = kinematics  # the model RealSensor uses for DIGIT poses
        self.estopped = False
        self._port = None
        self._packet = None
        self._reader = None
        self._last_q: np.ndarray | None = None
        self._last_ok = 0.0

    @property
    def name(self) -> str:
        return f"Dynamixel hand on {self.port} at {self.baudrate} baud"

    def set_joint_limits(self, limits: Sequence[Sequence[float]]) -> None:
        if self.joint_limits is None:
            self.joint_limits = np.asarray(limits, dtype=np.float64)

    def open(self) -> None:
        from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, PacketHandler, PortHandler

        if not os.path.exists(self.port):
            raise HardwareError(
                f"{self.name}: serial port {self.port} not found: connect the U2D2 or set sensor.hand.port"
            )
        self._port = PortHandler(self.port)
        try:
            opened = self._port.openPort() and self._port.setBaudRate(self.baudrate)
        except Exception as exc:  # pyserial raises SerialException / OSError on a bad device
            opened = False
            log.debug("opening %s failed: %s", self.port, exc)
        if not opened:
            self._port = None
            raise HardwareError(
                f"{self.name}: cannot open the port at this baud rate: check permissions or sensor.hand.baudrate"
            )
        self._packet = PacketHandler(2.0)
        missing = []
        for dxl_id in self.motor_ids:
            # A status packet lost on a busy bus (or a slow host) is not a missing motor.
            for _ in range(PING_ATTEMPTS):
                _, result, _ = self._packet.ping(self._port, dxl_id)
                if result == COMM_SUCCESS:
                    break
            else:
                missing.append(dxl_id)
        if missing:
            self.close()
            raise HardwareError(
                f"{self.name}: motors {missing} did not answer a ping: power the hand or fix sensor.hand.motor_ids"
            )
        self._reader = GroupSyncRead(
            self._port, self._packet, ADDR_PRESENT_POSITION, POSITION_BYTES
        )
        for dxl_id in self.motor_ids:
            self._reader.addParam(dxl_id)
        self._last_ok = time.monotonic()
        if self.control:
            if self.joint_limits is None:
                raise ConfigError(
                    "sensor.hand.control=true needs joint limits: set sensor.hand.joint_limits"
                )
            current = int(round(self.current_limit_ma / 2.69))  # X-series: 2.69 mA per unit
            for dxl_id in self.motor_ids:
                self._packet.write2ByteTxRx(self._port, dxl_id, ADDR_CURRENT_LIMIT, current)
                self._packet.write1ByteTxRx(self._port, dxl_id, ADDR_TORQUE_ENABLE, 1)

    def close(self) -> None:
        if self._port is None:
            return
        try:
            if self.control and not self.estopped:
                self._disable_torque()
        finally:
            self._port.closePort()
            self._port = None

    def _disable_torque(self) -> None:
        for dxl_id in self.motor_ids:
            self._packet.write1ByteTxOnly(self._port, dxl_id, ADDR_TORQUE_ENABLE, 0)

    def read_joints(self) -> np.ndarray:
        """Group sync read of the 16 present positions -> angles (rad), in motor_ids order."""
        from dynamixel_sdk import COMM_SUCCESS

        if self._port is None:
            raise RuntimeError(f"{self.name} is not open")
        result = self._reader.txRxPacket()
        raw = []
        if result == COMM_SUCCESS:
            for dxl_id in self.motor_ids:
                if not self._reader.isAvailable(dxl_id, ADDR_PRESENT_POSITION, POSITION_BYTES):
                    result = -1
                    break
                raw.append(self._reader.getData(dxl_id, ADDR_PRESENT_POSITION, POSITION_BYTES))
        now = time.monotonic()
        if result != COMM_SUCCESS:
            if now - self._last_ok > self.timeout_s:
                self.emergency_stop(f"no sync-read reply for {now - self._last_ok:.2f} s")
            if self._last_q is None:
                raise HardwareError(f"{self.name}: sync read of present positions failed")
            return self._last_q.copy()
        self._last_ok = now
        self._last_q = raw_to_radians(np.asarray(raw), self.zero_raw, self.signs)
        return self._last_q.copy()

    def emergency_stop(self, reason: str) -> None:
        if self.control and self._port is not None and not self.estopped:
            try:
                self._disable_torque()
            except Exception as exc:  # the port may be gone: the stop must still latch
                log.error("%s: torque disable failed during emergency stop: %s", self.name, exc)
        self.estopped = True
        raise HardwareError(
            f"{self.name}: emergency stop ({reason}); check the cable and power, then restart"
        )

    def command_positions(self, q_target: np.ndarray) -> np.ndarray:
        """Write goal positions clamped to the joint limits. Returns the raw goals sent."""
        from dynamixel_sdk import GroupSyncWrite

        if not self.control:
            raise ConfigError(
                f"{self.name}: commands are disabled; set sensor.hand.control=true to move the hand"
            )
        if self.estopped:
            raise HardwareError(f"{self.name}: emergency stop is latched; restart the run")
        if time.monotonic() - self._last_ok > self.timeout_s:
            self.emergency_stop("no position reading within the timeout before a command")
        q_target = np.asarray(q_target, dtype=np.float64)
        if q_target.shape != (16,):
            raise ValueError(f"q_target must have shape (16,), got {q_target.shape}")
        target = np.clip(q_target, self.joint_limits[:, 0], self.joint_limits[:, 1])
        raw = radians_to_raw(target, self.zero_raw, self.signs)
        writer = GroupSyncWrite(self._port, self._packet, ADDR_GOAL_POSITION, POSITION_BYTES)
        for dxl_id, value in zip(self.motor_ids, raw):
            writer.addParam(dxl_id, list(int(value & 0xFFFFFFFF).to_bytes(4, "little")))
        writer.txPacket()
        return raw
