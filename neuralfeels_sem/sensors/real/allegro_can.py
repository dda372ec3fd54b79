"""Allegro Hand V4 over CAN (python-can): joint positions in, optional torque commands out.

Reading is always allowed. Commands are refused unless `control=True`; targets are
clamped to the joint limits, torques are capped at `torque_limit` (fraction of full
scale), and when no position reply arrived for `timeout_s` the driver sends zero torque,
latches an emergency stop and raises HardwareError.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.errors import ConfigError, HardwareError
from neuralfeels_sem.sensors.real import allegro_protocol as proto

log = logging.getLogger(__name__)


class AllegroCAN:
    """One Allegro hand on a CAN channel (socketcan, pcan, virtual, ... as python-can names them)."""

    def __init__(
        self,
        channel: str = "can0",
        interface: str = "socketcan",
        hand_id: int = 0,
        bitrate: int = 1_000_000,
        timeout_s: float = 0.1,
        control: bool = False,
        torque_limit: float = 0.3,
        kp: float = 0.6,
        kd: float = 0.02,
        joint_limits: Sequence[Sequence[float]] | None = None,
        kinematics: str = "allegro",
    ) -> None:
        if timeout_s <= 0:
            raise ValueError(f"timeout_s={timeout_s} must be > 0")
        proto.can_id(0, hand_id)  # validates hand_id
        self.channel = channel
        self.interface = interface
        self.hand_id = hand_id
        self.bitrate = bitrate
        self.timeout_s = timeout_s
        self.control = control
        self.torque_limit = torque_limit
        self.kp, self.kd = kp, kd
        self.joint_limits = None if joint_limits is None else self._check_limits(joint_limits)
        self.kinematics = kinematics  # the model RealSensor uses for DIGIT poses
        self.estopped = False
        self._bus = None
        self._last_q: np.ndarray | None = None
        self._last_ok = 0.0
        self._last_read_time = 0.0

    @property
    def name(self) -> str:
        return f"Allegro hand on {self.interface}:{self.channel} (hand_id {self.hand_id})"

    @staticmethod
    def _check_limits(limits: Sequence[Sequence[float]]) -> np.ndarray:
        arr = np.asarray(limits, dtype=np.float64)
        if arr.shape != (proto.NUM_JOINTS, 2) or np.any(arr[:, 0] > arr[:, 1]):
            raise ValueError(f"joint_limits must be (16, 2) with low <= high, got {arr.shape}")
        return arr

    def set_joint_limits(self, limits: Sequence[Sequence[float]]) -> None:
        """Limits from the hand's kinematic model, used when none were configured."""
        if self.joint_limits is None:
            self.joint_limits = self._check_limits(limits)

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> None:
        import can

        try:
            kwargs = {} if self.interface == "virtual" else {"bitrate": self.bitrate}
            self._bus = can.Bus(interface=self.interface, channel=self.channel, **kwargs)
        except Exception as exc:  # python-can raises OSError, CanError or ImportError per backend
            raise HardwareError(
                f"{self.name}: cannot open the CAN channel ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}): "
                "connect the adapter or set sensor.hand.interface / sensor.hand.channel"
            ) from exc
        self._last_ok = time.monotonic()
        try:
            self.read_joints()
        except HardwareError:
            self.close()
            raise HardwareError(
                f"{self.name}: no answer to a position request within {self.timeout_s} s: "
                "power the hand on or check sensor.hand.hand_id"
            ) from None
        if self.control and self.joint_limits is None:
            raise ConfigError(
                "sensor.hand.control=true needs joint limits: set sensor.hand.joint_limits"
            )
        if self.control:
            self._send(proto.CMD_SYSTEM_ON, b"")

    def close(self) -> None:
        if self._bus is None:
            return
        try:
            if self.control and not self.estopped:
                self._send_zero_torque()
        finally:
            self._bus.shutdown()
            self._bus = None

    # ------------------------------------------------------------------ reading
    def _send(self, command: int, data: bytes, remote: bool = False) -> None:
        import can

        msg = can.Message(
            arbitration_id=proto.can_id(command, self.hand_id),
            data=data,
            is_remote_frame=remote,
            is_extended_id=False,
            dlc=8 if remote else len(data),
        )
        self._bus.send(msg)

    def read_joints(self) -> np.ndarray:
        """Request and read the 16 joint positions (rad), Allegro order."""
        if self._bus is None:
            raise RuntimeError(f"{self.name} is not open")
        q = np.full(proto.NUM_JOINTS, np.nan)
        for finger in range(proto.NUM_FINGERS):
            self._send(proto.RTR_FINGER_POSE + finger, b"", remote=True)
        missing = set(range(proto.NUM_FINGERS))
        deadline = time.monotonic() + self.timeout_s
        while missing:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            msg = self._bus.recv(timeout=remaining)
            if msg is None or msg.is_remote_frame or msg.is_error_frame:
                continue
            command, hand_id = proto.split_can_id(msg.arbitration_id)
            finger = command - proto.RTR_FINGER_POSE
            if hand_id != self.hand_id or finger not in missing or len(msg.data) != 8:
                continue
            q[4 * finger : 4 * finger + 4] = proto.decode_positions(msg.data)
            missing.discard(finger)
        now = time.monotonic()
        if missing:
            self._check_watchdog(now)
            if self._last_q is None:
                raise HardwareError(f"{self.name}: no position reply for fingers {sorted(missing)}")
            q[np.isnan(q)] = self._last_q[np.isnan(q)]  # a late finger keeps its last reading
            return q
        self._last_ok = now
        self._last_q = q
        self._last_read_time = now
        return q

    def _check_watchdog(self, now: float) -> None:
        if now - self._last_ok > self.timeout_s:
            self.emergency_stop(f"no position reply for {now - self._last_ok:.2f} s")

    # ------------------------------------------------------------------ control
    def emergency_stop(self, reason: str) -> None:
        """Zero torque, latch the stop, raise. Further commands are refused."""
        if self.control and self._bus is not None and not self.estopped:
            try:
                self._send_zero_torque()
            except Exception as exc:  # the bus may be gone: the stop must still latch
                log.error(
                    "%s: zero-torque command failed during emergency stop: %s", self.name, exc
                )
        self.estopped = True
        raise HardwareError(
            f"{self.name}: emergency stop ({reason}); check the cable and power, then restart"
        )

    def _send_zero_torque(self) -> None:
        for finger in range(proto.NUM_FINGERS):
            self._send(
                proto.CMD_SET_TORQUE + finger, proto.encode_torques(np.zeros(4, dtype=np.int64))
            )

    def _require_control(self) -> None:
        if not self.control:
            raise ConfigError(
                f"{self.name}: commands are disabled; set sensor.hand.control=true to move the hand"
            )
        if self.estopped:
            raise HardwareError(f"{self.name}: emergency stop is latched; restart the run")
        if self._bus is None:
            raise RuntimeError(f"{self.name} is not open")

    def send_torques(self, torque: np.ndarray) -> np.ndarray:
        """Send 16 normalised torques (1.0 = full scale), capped at torque_limit. Returns the PWM sent."""
        self._require_control()
        self._check_watchdog(time.monotonic())
        torque = np.asarray(torque, dtype=np.float64)
        if torque.shape != (proto.NUM_JOINTS,):
            raise ValueError(f"torque must have shape (16,), got {torque.shape}")
        pwm = proto.torque_to_pwm(torque, self.torque_limit)
        for finger in range(proto.NUM_FINGERS):
            self._send(
                proto.CMD_SET_TORQUE + finger,
                proto.encode_torques(pwm[4 * finger : 4 * finger + 4]),
            )
        return pwm

    def command_positions(self, q_target: np.ndarray) -> np.ndarray:
        """One PD step toward `q_target` (clamped to the joint limits). Returns the PWM sent."""
        self._require_control()
        q_target = np.asarray(q_target, dtype=np.float64)
        if q_target.shape != (proto.NUM_JOINTS,):
            raise ValueError(f"q_target must have shape (16,), got {q_target.shape}")
        previous, previous_time = self._last_q, self._last_read_time
        q = self.read_joints()
        target = np.clip(q_target, self.joint_limits[:, 0], self.joint_limits[:, 1])
        dq = np.zeros_like(q)
        if previous is not None and self._last_read_time > previous_time:
            dq = (q - previous) / (self._last_read_time - previous_time)
        return self.send_torques(self.kp * (target - q) - self.kd * dq)
