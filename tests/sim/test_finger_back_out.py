"""FingerControl._back_out: a finger the object has swallowed never ends the step inside it."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from neuralfeels_sem.core.digit import MAX_PENETRATION_M
from neuralfeels_sem.sim.finger_control import FingerControl
from neuralfeels_sem.sim.ik import FingerTarget
from neuralfeels_sem.sim.policy import FingerPlan
from neuralfeels_sem.sim.rig_params import REST_Q

ADR = {"index": np.arange(0, 4), "middle": np.arange(4, 8)}
SWALLOWED_M = 0.015  # how deep the object reaches into a gel that is not at rest


class TwoFingers(FingerControl):
    """Two fingers over a stand-in scene: a finger away from rest is SWALLOWED_M deep, unless
    press control can slide it back (can_press_back); at rest nothing touches it."""

    def __init__(self, can_press_back: bool) -> None:
        self.fingers = list(ADR)
        self.press = dict.fromkeys(ADR, 0.0015)
        self.scene = SimpleNamespace(data=SimpleNamespace(qpos=np.full(16, 0.5)))
        self.ik = SimpleNamespace(
            qpos_adr=ADR, forward=lambda: None, gel_pose=lambda f: (np.zeros(3), np.eye(3))
        )
        self.can_press_back = can_press_back
        self.pressed_back: list[str] = []

    def press_depth(self, finger: str) -> float:
        at_rest = np.allclose(self.scene.data.qpos[ADR[finger]], REST_Q[ADR[finger]])
        return -0.001 if at_rest else SWALLOWED_M

    def _press_control(self, fingers, plans, targets, errors, press) -> None:
        self.pressed_back += list(fingers)
        for f in fingers:
            press[f] = self.press[f] if self.can_press_back else SWALLOWED_M


def run_back_out(
    rig: TwoFingers, middle_press_m: float
) -> tuple[dict[str, float], dict[str, float]]:
    """Press and IK error of both fingers after _back_out, index swallowed."""
    plans = {f: FingerPlan(np.zeros(3), np.array([0.0, 0.0, 1.0]), False, 0, None) for f in ADR}
    targets = {f: FingerTarget(np.array([0.0, 0.0, 0.01]), np.array([0.0, 0.0, 1.0])) for f in ADR}
    errors = dict.fromkeys(ADR, 0.0)
    press = {"index": SWALLOWED_M, "middle": middle_press_m}
    rig._back_out(plans, targets, errors, press)
    assert errors["middle"] == 0.0  # a finger not inside is left as it was
    return press, errors


def test_a_swallowed_finger_is_pressed_back_to_its_firmness() -> None:
    rig = TwoFingers(can_press_back=True)
    press, errors = run_back_out(rig, middle_press_m=0.0015)
    assert rig.pressed_back == ["index"]
    assert press["index"] == rig.press["index"]
    assert not np.allclose(rig.scene.data.qpos[:4], REST_Q[:4])  # no need to go to rest
    assert errors["index"] == 0.0


def test_a_finger_press_control_cannot_free_goes_to_rest() -> None:
    rig = TwoFingers(can_press_back=False)
    press, errors = run_back_out(rig, middle_press_m=MAX_PENETRATION_M)  # at the limit
    assert rig.pressed_back == ["index"]
    np.testing.assert_array_equal(rig.scene.data.qpos[:4], REST_Q[:4])
    np.testing.assert_array_equal(rig.scene.data.qpos[4:8], 0.5)  # the other finger stays
    assert press["index"] < 0.0 and press["middle"] == MAX_PENETRATION_M
    assert errors["index"] == 0.01  # from its target to the gel at rest
