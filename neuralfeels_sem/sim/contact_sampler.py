"""New contacts for the rig's fingers: reachable postures whose pressed gel meets the object.

A mixin of SimRig (see SimRig._sample_contact, which GaitingPolicy calls): it reads the
rig's scene, probe data (`_probe`, `_probe_ik`), IK, trajectory, policy and press
depths, and keeps per finger the postures that touched (`_touched`) and, per finger and
trajectory segment, the postures that come near the object (`_libraries`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from neuralfeels_sem.core.digit import GEL_WIDTH_M
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sim.ik import FingerTarget
from neuralfeels_sem.sim.policy import Busy, Contact
from neuralfeels_sem.sim.rig_params import (
    BOTTOM_COS,
    COMPAT_CANDIDATES,
    ENOUGH_TOUCHES,
    FINGER_CLEARANCE_M,
    FIRST_TRIES,
    GOOD_CONTACT_RAYS,
    LIBRARY_INSIDE_M,
    LIBRARY_OUTSIDE_M,
    LIBRARY_TRIES,
    LOCAL_JITTER_RAD,
    LOCAL_SHARE,
    MAX_SHIFT_M,
    MIN_CONTACT_RAYS,
    MIN_LIBRARY,
    MIN_PRESS_M,
    MIN_PRESSED_RAYS,
    NOMINAL_Q,
    PRESS_ROUNDS,
    PRESS_SHORTFALL_M,
    PRESS_TOLERANCE_M,
    PROFILE_BIN_M,
    RECENT,
    REST_Q,
    SAMPLE_BOX,
    SAMPLE_TRIES,
    VERIFY_CANDIDATES,
)
from neuralfeels_sem.sim.rig_probes import GEL_GRID
from neuralfeels_sem.sim.trajectory import perpendicular_basis

# A sampled touch: (-contact rays, splay, |shift|, draw order, object-frame point, posture);
# sorted on [:4].
Touch = tuple


class ContactSampler:
    """Draws, screens, ranks and verifies contact postures (GaitingPolicy's sampler)."""

    def _sample_contact(
        self, finger: str, touchdown_s: float, rng: np.random.Generator, busy: list[Busy] = ()
    ) -> Contact | None:
        """A reachable touch: a random posture whose gel, pushed along its pad, meets the object.

        Postures come from the finger's library (_library) and, half of them, from around
        its latest touches. A posture qualifies when the object lies within MAX_SHIFT_M
        along the pad and, pressed to the finger's firmness, covers at least
        MIN_CONTACT_RAYS of the gel's rays: the pad may be tilted against the surface, which
        is how the index and ring fingertips meet an object narrower than the finger
        spacing. It must keep FINGER_CLEARANCE_M from the firm `busy` postures. Ranked: most
        contact (up to GOOD_CONTACT_RAYS), abduction nearest the natural one (a finger
        turned aside takes its neighbour's room), least shift; the best few are re-ranked by
        the room they leave the other fingers. The first that the IK presses to the
        firmness and that is still clear is the touch. If only neighbours are in the way,
        the finger claims the best blocked touch instead (see GaitingPolicy.busy).
        With a planner (sensor.policy=active, sim/touch_planner.py), more touches are
        screened and ranked by the map's touch score instead of by room: the best-scoring
        one that verifies is the touch.
        """
        postures = self._draw_postures(finger, touchdown_s, rng)
        world_T_object = self.trajectory.pose(touchdown_s)
        self.scene.set_object_pose(world_T_object, self._probe)
        press = self.press.get(finger, 0.0)
        firm = [(b.finger, b.posture) for b in busy if b.firm]
        planner = getattr(self, "planner", None)
        enough = ENOUGH_TOUCHES if planner is None else planner.config.candidates
        touches = self._screen(finger, postures, world_T_object, press, enough)
        if planner is not None and touches:
            touches = self._by_score(planner, touches, touchdown_s)
        candidates, blocked = self._split_clear(finger, touches, firm)
        if not candidates:
            if blocked:
                # Only the neighbours are in the way: claim the best blocked touch, so that
                # their next contacts leave room for it, and look there first next time.
                claim = min(blocked, key=lambda c: c[:4])[-1]
                self.policy.claims[finger] = claim
                self._touched[finger].append(claim)
            return None
        order = candidates  # active: best score first, as _by_score left them
        if planner is None:
            head = self._rank_by_room(finger, candidates[:COMPAT_CANDIDATES], busy)
            order = head + candidates[COMPAT_CANDIDATES:]
        contact = self._verify(finger, order[:VERIFY_CANDIDATES], press, firm, world_T_object)
        if contact is None:
            self._touched[finger].append(candidates[0][-1])  # nearly: look around there next time
        return contact

    def _by_score(self, planner, touches: list[Touch], touchdown_s: float) -> list[Touch]:
        """Screened touches best score first (sensor.policy=active); may start a regrasp."""
        contact = np.array([-c[0] / GOOD_CONTACT_RAYS for c in touches])  # full: 1
        points = np.array([c[4] for c in touches])
        order, scores = planner.rank(points, contact)
        height = self._hotspot_height(planner, touchdown_s)
        reachable = planner.confirm_reachable(points)
        if planner.note_choice(touchdown_s, float(scores.max()), height, reachable):
            self._regrasp(touchdown_s)
        self._consider_turn(points, touchdown_s)
        return [touches[i] for i in order]

    def _hotspot_height(self, planner, t: float) -> float | None:
        """How far (m) the advice's hotspot lies from the grasp centre's height along the
        axis the object turns about at t (None without advice, or when no regrasp asks for
        it): the fingers press around that height, so a hotspot far from it is out of the
        current turn's reach."""
        if planner.advice is None or planner.config.out_of_reach_m is None:
            return None  # scoring every surface sample for the hotspot is not free
        spot = planner.advice.hotspot()
        if spot is None:
            return None
        world_T_object = self.trajectory.pose(t)
        axis = self.trajectory.segment_axis(self.trajectory.segment(t))
        world = world_T_object[:3, :3] @ spot + world_T_object[:3, 3] - self.trajectory.centre
        return abs(float(axis @ world))

    def _draw_postures(
        self, finger: str, touchdown_s: float, rng: np.random.Generator
    ) -> np.ndarray:
        """Postures to try: from the finger's library (or box), half around its latest touches."""
        box = SAMPLE_BOX[finger]
        library = self._library(finger, self.trajectory.segment(touchdown_s))
        memory = self._touched[finger]
        tries = SAMPLE_TRIES if memory else FIRST_TRIES  # nothing to start from yet
        if len(library) >= MIN_LIBRARY:
            postures = library[rng.integers(len(library), size=tries)]
        else:
            postures = rng.uniform(box[:, 0], box[:, 1], (tries, 4))
        if memory:
            n_local = int(LOCAL_SHARE * SAMPLE_TRIES)
            seeds = np.array(memory)[rng.integers(len(memory), size=n_local)]
            postures[:n_local] = seeds + rng.normal(0.0, LOCAL_JITTER_RAD, (n_local, 4))
            postures[0] = memory[-1]  # the latest touch (or claim) itself
        return np.clip(postures, box[:, 0], box[:, 1])

    def _screen(
        self,
        finger: str,
        postures: np.ndarray,
        world_T_object: np.ndarray,
        press: float,
        enough: int = ENOUGH_TOUCHES,
    ) -> list[Touch]:
        """Postures whose gel, shifted along its pad by under MAX_SHIFT_M, meets the object; best first.

        Stops once `enough` qualify. Each carries the object-frame surface point its gel
        meets first.
        """
        model, data = self.scene.model, self._probe
        centre = world_T_object[:3, 3]
        object_T_world = invert_pose(world_T_object)
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
        within = self.obj.bounds_radius + GEL_WIDTH_M + MAX_SHIFT_M
        touches = []
        for q in postures:
            data.qpos[joints] = q
            mujoco.mj_kinematics(model, data)
            gel, pad = self._gel(model, data, finger)
            to_centre = centre - gel
            if to_centre @ to_centre > within * within or to_centre @ pad <= 0.0:
                continue  # out of reach, or the pad faces away from the object
            reach, hits, _ = self._reach(finger, data)
            deepest = reach.max()
            shift = press - deepest  # move along the pad by this to press by `press`
            rays = int(np.count_nonzero(reach >= deepest - press))
            if not -MAX_SHIFT_M < shift < MAX_SHIFT_M or rays < MIN_CONTACT_RAYS:
                continue
            splay = round(abs(q[0] - NOMINAL_Q[4 * i]) / 0.1)
            # the surface point the gel meets first (its deepest ray's hit)
            point = object_T_world[:3, :3] @ hits[int(np.argmax(reach))] + object_T_world[:3, 3]
            touches.append(
                (-min(rays, GOOD_CONTACT_RAYS), splay, abs(shift), len(touches), point, q)
            )
            if len(touches) >= enough:
                break  # a wide object: plenty to choose from
        touches.sort(key=lambda c: c[:4])
        return touches

    def _split_clear(
        self, finger: str, touches: list[Touch], firm: list[tuple[str, np.ndarray]]
    ) -> tuple[list[Touch], list[Touch]]:
        """Touches clear of the firm postures (up to VERIFY_CANDIDATES), and those blocked."""
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
        candidates, blocked = [], []
        for c in touches:  # clearance is the costlier test: best first, as many as needed
            self._probe.qpos[joints] = c[-1]
            (candidates if self._clear_of(finger, firm) else blocked).append(c)
            if len(candidates) >= VERIFY_CANDIDATES:
                break
        return candidates, blocked

    def _rank_by_room(self, finger: str, head: list[Touch], busy: list[Busy]) -> list[Touch]:
        """Re-rank the best few touches by the room they leave the other fingers.

        The room is where the others touched lately (their claims and latest touches): on
        a narrow object a touch in the wrong place shuts a neighbour out.
        """
        others = [(b.finger, b.posture) for b in busy if not b.firm] + [
            (g, p) for g in self.fingers if g != finger for p in list(self._touched[g])[-RECENT:]
        ]
        if not others:
            return head
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
        for n, c in enumerate(head):
            self._probe.qpos[joints] = c[-1]
            free = sum(self._gap_to(finger, g, p) >= FINGER_CLEARANCE_M for g, p in others)
            head[n] = (-round(4 * free / len(others)), *c)
        head.sort(key=lambda c: c[:5])
        return [c[1:] for c in head]

    def _verify(
        self,
        finger: str,
        order: list[Touch],
        press: float,
        firm: list[tuple[str, np.ndarray]],
        world_T_object: np.ndarray,
    ) -> Contact | None:
        """The first touch that the IK presses to the firmness and that is still clear."""
        model, data = self.scene.model, self._probe
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
        up = self.scene.world_T_palm[:3, 0]
        rest = [(g, REST_Q[self.ik.qpos_adr[g]]) for g in self.fingers if g != finger]
        for *_, q in order:
            data.qpos[joints] = q
            mujoco.mj_kinematics(model, data)
            if not self._press_probe(finger, press):
                continue
            reach, _, normals = self._reach(finger, data, normals=True)
            deepest = reach.max()
            normal = normals[int(np.argmax(reach))]
            if (
                np.count_nonzero(reach >= deepest - press) < MIN_PRESSED_RAYS
                or normal @ up < -BOTTOM_COS
                or self._on_flat_base(normal, world_T_object)
                or not self._clear_of(finger, firm)  # the IK moved the finger
                # and a neighbour must be able to get out of its way (see _keep_apart)
                or not self._clear_of(finger, rest)
            ):
                continue
            solved = data.qpos[joints].copy()
            self._touched[finger].append(solved)
            gel, pad = self._gel(model, data, finger)
            object_T_world = invert_pose(world_T_object)
            rot = object_T_world[:3, :3]
            return Contact(
                point=rot @ (gel - deepest * pad) + object_T_world[:3, 3],
                normal=rot @ normal,
                pad=rot @ pad,
                posture=solved,
            )
        return None

    def _library(self, finger: str, segment: int = 0) -> np.ndarray:
        """Postures of the finger's SAMPLE_BOX whose gel comes near the object as it turns.

        (About the segment's centre: the grasp centre, shifted where a regrasp slid the object.)

        The object sweeps a solid of revolution about the rotation axis; at each height
        along the axis its surface lies between its narrowest and widest radius (24 sectors).
        Postures whose gel centre lies in that band (widened by LIBRARY_INSIDE_M and
        LIBRARY_OUTSIDE_M) and whose pad faces the axis are kept: on a narrow object only a
        few percent of the box touch it, about three times as many of these. Built once per
        finger and trajectory segment (an alternating axis sweeps another solid each
        time), deterministic.
        """
        key = (finger, segment)
        if key in self._libraries:
            return self._libraries[key]
        axis = self.trajectory.segment_axis(segment)
        low, r_in, r_out = self._profile(segment, axis)
        box = SAMPLE_BOX[finger]
        # segment 0 keeps the single-axis seed, so one-axis runs are unchanged
        stream = [self.seed, FINGERS.index(finger), 7] + ([segment] if segment else [])
        rng = np.random.default_rng(stream)
        postures = rng.uniform(box[:, 0], box[:, 1], (LIBRARY_TRIES, 4))
        model, data = self.scene.model, mujoco.MjData(self.scene.model)
        i = FINGERS.index(finger)
        keep = []
        for q in postures:
            data.qpos[4 * i : 4 * i + 4] = q
            mujoco.mj_kinematics(model, data)
            gel, pad = self._gel(model, data, finger)
            rel = gel - self.trajectory.segment_centre(segment)
            height = rel @ axis
            radial = rel - height * axis
            r = np.linalg.norm(radial)
            b = int(np.floor(height / PROFILE_BIN_M)) - low
            if not 0 <= b < len(r_out) or r < 1e-9 or pad @ radial > 0:
                continue  # beyond the object's ends along the axis, or facing away
            if r_in[b] - LIBRARY_INSIDE_M <= r <= r_out[b] + LIBRARY_OUTSIDE_M:
                keep.append(q)
        self._libraries[key] = np.array(keep).reshape(-1, 4)
        return self._libraries[key]

    def _profile(self, segment: int, axis: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """The swept solid of a segment: lowest height bin, per bin narrowest and widest radius.

        With sensor.grasp_height=follow the object also rises and falls within a segment;
        the profile keeps its height at the segment's settled time (an approximation the
        library's LIBRARY_OUTSIDE_M of slack absorbs only in part). Screening against the
        swept shape of a whole turn instead mapped the ten development objects where
        follow differs worse (87.4 % mean-class against 92.6, two mapping seeds)."""
        if segment not in self._profiles:
            pose = self.trajectory.pose(self.trajectory.settled(segment))
            centre = self.trajectory.segment_centre(segment)
            rel = np.asarray(self.obj.mesh.vertices) @ pose[:3, :3].T + pose[:3, 3] - centre
            height = rel @ axis
            radial = rel - np.outer(height, axis)
            u, v = perpendicular_basis(axis)
            az = np.floor((np.arctan2(radial @ v, radial @ u) + np.pi) / (2 * np.pi) * 24)
            hb = np.floor(height / PROFILE_BIN_M).astype(int)
            outer = np.zeros((hb.max() - hb.min() + 1, 24))
            cells = (hb - hb.min(), np.clip(az, 0, 23).astype(int))
            np.maximum.at(outer, cells, np.linalg.norm(radial, axis=1))
            self._profiles[segment] = (hb.min(), outer.min(axis=1), outer.max(axis=1))
        return self._profiles[segment]

    def _press_probe(self, finger: str, press: float) -> bool:
        """Slide the probe's finger along its pad until the object reaches `press` into the gel.

        The deepest-reaching point of the gel is what touches, so the IK moves that point
        (a tilted pad then turns about it). A tilted pad gains reach faster or slower than it
        moves, by the slope under it: the gain is estimated from each round. False if the
        object leaves the gel's view or the press ends more than PRESS_TOLERANCE_M deeper or
        PRESS_SHORTFALL_M shallower than asked (a finger at the edge of its reach).
        """
        gain = 1.0
        reach = self._reach(finger, self._probe, points=False)[0]
        for _ in range(PRESS_ROUNDS):
            k = int(np.argmax(reach))
            if not np.isfinite(reach[k]):
                return False  # the object slipped out of the gel's view
            if abs(reach[k] - press) < PRESS_TOLERANCE_M:
                return True
            move = (press - reach[k]) / gain
            _, pad = self._probe_ik.gel_pose(finger)
            point = self._probe_ik.gel_point(finger, GEL_GRID[k])
            target = FingerTarget(point + move * pad, pad, GEL_GRID[k])
            # Where the joint limits stop it short, the next round goes on from there.
            self._probe_ik.solve({finger: target})
            before, reach = reach[k], self._reach(finger, self._probe, points=False)[0]
            gain = float(np.clip((reach.max() - before) / move, 0.3, 4.0))
        # At the edge of its reach a finger may press less than its firmness, not much less.
        deepest = reach.max()
        return bool(
            max(MIN_PRESS_M, press - PRESS_SHORTFALL_M) <= deepest < press + PRESS_TOLERANCE_M
        )

    def _gap_to(self, finger: str, other: str, posture: np.ndarray) -> float:
        """Gap between `finger` as posed in the probe and `other` at `posture` (m, up to 1 cm)."""
        data = self._probe
        adr = self.ik.qpos_adr[other]
        before = data.qpos[adr].copy()
        data.qpos[adr] = posture
        mujoco.mj_kinematics(self.scene.model, data)
        gap = self._gap(data, finger, other)
        data.qpos[adr] = before
        mujoco.mj_kinematics(self.scene.model, data)
        return gap

    def _clear_of(self, finger: str, postures: list[tuple[str, np.ndarray]]) -> bool:
        """Whether `finger`, as posed in the probe, keeps FINGER_CLEARANCE_M from these postures."""
        return all(
            self._gap_to(finger, other, posture) >= FINGER_CLEARANCE_M
            for other, posture in postures
            if other != finger
        )
