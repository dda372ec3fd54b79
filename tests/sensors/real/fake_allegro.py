"""A thread that speaks the Allegro V4 CAN protocol on python-can's virtual bus, like a hand."""

from __future__ import annotations

import threading

import can
import numpy as np

from neuralfeels_sem.sensors.real import allegro_protocol as proto


class FakeAllegro:
    """Answers position requests with `self.q` and records every torque frame it receives."""

    def __init__(self, channel: str, hand_id: int = 0, q: np.ndarray | None = None) -> None:
        self.hand_id = hand_id
        self.q = np.zeros(16) if q is None else np.asarray(q, dtype=np.float64)
        self.answering = True
        self.torques: list[tuple[int, np.ndarray]] = []  # (finger, pwm)
        self.commands: list[int] = []
        self._bus = can.Bus(interface="virtual", channel=channel)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def __enter__(self) -> FakeAllegro:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self._bus.shutdown()

    def _loop(self) -> None:
        while not self._stop.is_set():
            msg = self._bus.recv(timeout=0.01)
            if msg is None:
                continue
            command, hand_id = proto.split_can_id(msg.arbitration_id)
            if hand_id != self.hand_id:
                continue
            self.commands.append(command)
            finger = command - proto.RTR_FINGER_POSE
            if msg.is_remote_frame and 0 <= finger < 4 and self.answering:
                payload = proto.encode_positions(self.q[4 * finger : 4 * finger + 4])
                self._bus.send(
                    can.Message(
                        arbitration_id=msg.arbitration_id, data=payload, is_extended_id=False
                    )
                )
            elif proto.CMD_SET_TORQUE <= command < proto.CMD_SET_TORQUE + 4:
                self.torques.append(
                    (command - proto.CMD_SET_TORQUE, proto.decode_torques(msg.data))
                )
