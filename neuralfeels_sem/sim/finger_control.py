"""Per time step corrections of the rig's IK solution: press depth control, fingers kept apart.

A mixin of SimRig: it reads the rig's scene, IK, fingers and press depths (firmness).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.digit import MAX_PENETRATION_M
from neuralfeels_sem.sim.ik import FingerTarget
from neuralfeels_sem.sim.policy import FingerPlan
from neuralfeels_sem.sim.rig_params import OVERLAP_TOLERANCE_M, PRESS_CONTROL_ROUNDS, REST_Q
from neuralfeels_sem.sim.rig_probes import PROBE_BACK_M


class FingerControl:
    """Slides fingers to their firmness along their pads and pulls overlapping fingers back."""

    def _keep_apart(self, plans: dict[str, FingerPlan], previous: np.ndarray) -> set[str]:
        """Put back fingers that the IK moved into another finger; returns the fingers put back.

        Of an overlapping pair, the finger not in its contact phase goes back to where it was
        (both, if both are in it) and, if the pair still overlaps, out of the way to its
        rest posture (bent back; touches are planned clear of the others' rest postures). Contacts are planned clear of each
        other (see _sample_contact): this catches a finger swinging past a neighbour on its
        way to the next touch, or hovering where a neighbour's touch lands.
        """
        data = self.scene.data
        moved: set[str] = set()
        for _ in range(2 * len(self.fingers)):
            clashes = [
                (a, b)
                for a, b in itertools.combinations(self.fingers, 2)
                if self._gap(data, a, b, 0.0) < -OVERLAP_TOLERANCE_M
            ]
            if not clashes:
                break
            for pair in clashes:
                free = [f for f in pair if not plans[f].touching] or list(pair)
                for f in free:
                    adr = self.ik.qpos_adr[f]
                    # Back to where it was; if that clashes too, out of the way (bent back).
                    data.qpos[adr] = REST_Q[adr] if f in moved else previous[adr]
                    moved.add(f)
            self.ik.forward()
        return moved

    def _press_control(
        self,
        fingers: Sequence[str],
        plans: dict[str, FingerPlan],
        targets: dict[str, FingerTarget],
        errors: dict[str, float],
        press: dict[str, float],
    ) -> None:
        """Slide fingers along their pads until the object reaches their firmness into the gel.

        Touching fingers are driven to their firmness, the others only backed off if they
        press deeper. A pad tilted against the surface gains reach faster or slower than it
        moves (the slope under its edge), so the gain is estimated per finger from each
        round. Updates targets, errors and press in place.
        """
        gain = dict.fromkeys(fingers, 1.0)
        for _ in range(PRESS_CONTROL_ROUNDS):
            moves = {}
            for f in fingers:
                goal = self.press[f]
                delta = press[f] - goal if plans[f].touching else max(0.0, press[f] - goal)
                if plans[f].touching and press[f] <= -PROBE_BACK_M + 1e-9:
                    continue  # nothing under the gel: IK error decides
                if abs(delta) > 1e-4:
                    moves[f] = -delta / gain[f]
            if not moves:
                return
            shifted = {}
            for f, move in moves.items():
                _, pad = self.ik.gel_pose(f)
                shifted[f] = FingerTarget(
                    targets[f].gel_position + move * pad, targets[f].pad_direction
                )
            errors.update(self.ik.solve(shifted))
            targets.update(shifted)
            for f, move in moves.items():
                before, press[f] = press[f], self.press_depth(f)
                if press[f] > -PROBE_BACK_M and before > -PROBE_BACK_M:
                    gain[f] = float(np.clip((press[f] - before) / move, 0.3, 4.0))

    def _back_out(
        self,
        plans: dict[str, FingerPlan],
        targets: dict[str, FingerTarget],
        errors: dict[str, float],
        press: dict[str, float],
    ) -> None:
        """No finger ends a step inside the object, deeper than a gel can be pressed.

        A finger between touches whose IK target the turning object has swallowed, or one
        _keep_apart put back to where it was, can sit 19 mm deep; no real finger gets there,
        and its DIGIT would show a full press whose contact points lie inside the object.
        Such a finger is pressed back to its firmness, and if that cannot get it out, goes to
        its rest posture. Updates targets, errors and press in place.
        """
        inside = [f for f in self.fingers if press[f] > MAX_PENETRATION_M]
        if not inside:
            return
        self._press_control(inside, plans, targets, errors, press)
        still = [f for f in inside if press[f] > MAX_PENETRATION_M]
        if not still:
            return
        for f in still:
            adr = self.ik.qpos_adr[f]
            self.scene.data.qpos[adr] = REST_Q[adr]
        self.ik.forward()
        for f in still:
            press[f] = self.press_depth(f)
            errors[f] = float(np.linalg.norm(targets[f].gel_position - self.ik.gel_pose(f)[0]))
