"""The simulated rig over time: object trajectory + gaiting policy + IK + press control on the MuJoCo scene.

`SimRig.state_at(t)` (t non-decreasing) moves the object's mocap body along its
trajectory, asks the policy for every finger's target, solves IK for the joint angles
and corrects each finger along its pad direction so that the object reaches into the
gel by the finger's firmness (measured with ray casts over the gel area: a finger
whose pad cannot lie flat on the surface still presses by that depth at its deepest
point). Fingers that the IK moved into each other are put back (_keep_apart). The
result is written to qpos and the scene is forwarded (mj_forward).

New contacts come from `_sample_contact`: postures of each finger, drawn where its gel
comes near the turning object, whose gel pushed along its pad touches the object, clear
of the other fingers. The index and ring fingers converge on the middle one with their
MCP abduction, and on an object narrower than the 43.5 mm finger spacing their pads meet
its flanks tilted, with the gel's inner edge; where three fingers do not fit at once,
they take turns (GaitingPolicy.busy).
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M, GEL_HEIGHT_M, GEL_WIDTH_M, MAX_PENETRATION_M
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.camera_renderer import front_left_camera_pose
from neuralfeels_sem.sim.hand_model import PALM_FACE_X
from neuralfeels_sem.sim.ik import FingerTarget, FingertipIK
from neuralfeels_sem.sim.kinematics import HandKinematics
from neuralfeels_sem.sim.policy import Busy, Contact, FingerPlan, GaitingPolicy
from neuralfeels_sem.sim.scene import SimScene
from neuralfeels_sem.sim.trajectory import ObjectTrajectory, perpendicular_basis

DEFAULT_PRESS_M = {"index": 0.0015, "middle": 0.0015, "ring": 0.0015, "thumb": 0.0007}
# Posture of fingers that take no part (bent back, away from the object) and the IK start.
REST_Q = np.array([0.0, -0.19, 0.0, 0.0] * 3 + [0.263, 0.0, 0.0, 0.0])
# Natural grasp posture: pads of fingers and thumb face each other; index and ring turned
# in toward the middle finger as far as their DIGITs stay clear of its DIGIT (5 mm).
NOMINAL_Q = np.array(
    [0.25, 0.6, 0.6, 0.5, 0.0, 0.6, 0.6, 0.5, -0.25, 0.6, 0.6, 0.5, 1.25, 0.1, 0.3, 0.3]
)
# Joint boxes (rad, within the limits) contact postures are drawn from. Index and ring may
# converge on the middle finger with their MCP abduction (j0) up to the joint limit: their
# pads then reach objects narrower than the 43.5 mm finger spacing (with the gel's inner
# edge where the surface turns away). The middle finger stays central; the thumb near its
# natural posture (it opposes the middle finger).
SAMPLE_BOX = {
    "index": np.array([[0.0, 0.47], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "middle": np.array([[-0.3, 0.3], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "ring": np.array([[-0.47, 0.0], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "thumb": np.array([[0.8, 1.396], [-0.105, 0.9], [-0.189, 1.2], [-0.162, 1.2]]),
}
SAMPLE_TRIES = 96  # postures drawn per new contact
ENOUGH_TOUCHES = 24  # stop drawing once this many qualify
FIRST_TRIES = 288  # while the finger has not touched yet
LIBRARY_TRIES = 2000  # box postures screened once per finger for ones near the object
# A touching gel centre lies at most the press inside the surface, and outside by up to
# MAX_SHIFT_M plus, for a tilted pad touching with its edge, most of the gel's half width.
LIBRARY_INSIDE_M, LIBRARY_OUTSIDE_M = 0.003, 0.025
MIN_LIBRARY = 32  # fewer screened postures than this: draw from the whole box
PROFILE_BIN_M = 0.004  # height bins of the object's swept profile
LOCAL_SHARE = 0.5  # share drawn around postures that touched before (narrow objects: few do)
LOCAL_JITTER_RAD = 0.12
MEMORY = 12  # touching postures remembered per finger
COMPAT_CANDIDATES = 5  # best sampled touches ranked by the room they leave the others
RECENT = 2  # latest touches per other finger that count as its room
VERIFY_CANDIDATES = 10  # best sampled touches checked by IK and for clearance
PRESS_CONTROL_ROUNDS = 3  # per time step
PRESS_ROUNDS = 4  # IK rounds that bring a sampled touch to its press depth
PRESS_TOLERANCE_M = 3e-4
PRESS_SHORTFALL_M = 1e-3  # a finger at the edge of its reach may press this much less
MIN_PRESS_M = 3e-4
MAX_SHIFT_M = 0.015  # a sampled gel may be at most this far from its touch along its pad
MIN_CONTACT_RAYS = 3  # of the 25 gel rays, in contact at the press depth (a tilted touch
GOOD_CONTACT_RAYS = 10  # meets the object with its edge); more than GOOD counts the same
MIN_PRESSED_RAYS = 2  # once pressed to its firmness (the IK turns a tilted pad a little)
BOTTOM_COS = 0.7  # no touches where the surface faces the palm this squarely (the resting
# bottom of an object is unlabelled, and there is no room there for a finger), nor, on an
# object with a flat base, where it faces the object's own -z this squarely: the base it
# stands on, which a second rotation axis brings round to the fingers. A flat base fills
# the whole gel, unlike any press the classifier was trained on.
FLAT_BASE_SHARE = 0.02  # of the surface area facing -z within 8 degrees: a flat base
FINGER_CLEARANCE_M = 0.001  # gap kept between a new contact's finger and the busy fingers
OVERLAP_TOLERANCE_M = 0.001  # fingers closer than -this are pulled apart at run time
# Order in which fingers plan (and so claim room for) new contacts when several do at once:
# the middle finger first, it sits between the others and the thumb opposes it.
PLAN_ORDER = ("middle", "thumb", "index", "ring")
HOVER_BACK_M = 0.015  # a finger with nothing to touch waits this far behind its natural place
PALM_CLEARANCE_M = 0.008
# The object sits this much further out along the fingers than midway between the middle
# finger's and the thumb's natural pads: index and ring, which reach the object only
# where their lines converge on it, gain much more room than the thumb loses.
GRASP_REACH_M = 0.015
RETRY_IK_M = 0.001  # IK error above which a finger retries from its contact's posture
LOST_CONTACT_M = 0.003  # a touching finger further than this from its target gives up the contact
_GRID = np.stack(
    np.meshgrid(
        np.linspace(-0.45, 0.45, 5) * GEL_WIDTH_M, np.linspace(-0.45, 0.45, 5) * GEL_HEIGHT_M
    ),
    -1,
).reshape(-1, 2)
_PROBE_BACK_M = 0.01  # reach reported when nothing is in view (m behind the gel surface)
# Unit rays from the DIGIT camera through the grid points on the gel (sensor frame).
_GRID_RAYS = np.column_stack([_GRID, np.full(len(_GRID), GEL_DISTANCE_M)])
_GRID_RAYS /= np.linalg.norm(_GRID_RAYS, axis=1, keepdims=True)
_CENTRE_FIRST = np.argsort(np.linalg.norm(_GRID, axis=1), kind="stable")  # rays, inner first


def flat_base_share(mesh) -> float:
    """Share of a mesh's surface area facing its -z within 8 degrees (a flat base)."""
    area = np.asarray(mesh.area_faces)
    down = np.asarray(mesh.face_normals)[:, 2] < -0.99
    return float(area[down].sum() / max(area.sum(), 1e-12))


def _gel_site(model: mujoco.MjModel, finger: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{finger}_gel")


@dataclass
class RigState:
    time_s: float
    joint_positions: np.ndarray  # (16,)
    world_T_object: np.ndarray
    world_T_sensor: dict[str, np.ndarray]
    touching: dict[str, bool]  # finger in its contact phase and at its target
    contact_point: dict[str, np.ndarray | None]  # object-frame point being touched
    press_m: dict[str, float]  # deepest reach of the object into the gel (<= 0: no contact)
    ik_error_m: dict[str, float]


class SimRig:
    """One object turning in the hand. Construction is cheap; `open()` compiles the scene."""

    def __init__(
        self,
        obj: MaterialObject,
        fingers: Sequence[str] = FINGERS,
        axis: Sequence[float] = (0.0, 0.0, 1.0),
        speed_deg_s: float = 30.0,
        wobble_deg: float = 4.0,
        press_depth_m: dict[str, float] | None = None,
        period_s: float = 1.2,
        contact_fraction: float = 0.75,
        world_T_palm: np.ndarray | None = None,
        world_T_camera: np.ndarray | None = None,
        seed: int = 0,
        alternate_axis: Sequence[float] | None = None,
        alternate_every_s: float = 5.0,
    ) -> None:
        unknown = set(fingers) - set(FINGERS)
        if unknown or not fingers:
            raise ValueError(
                f"fingers must be a non-empty subset of {FINGERS}, got {list(fingers)}"
            )
        self.obj = obj
        self.fingers = tuple(f for f in FINGERS if f in fingers)
        self.axis = np.asarray(axis, np.float64)
        self.alternate_axis = None if alternate_axis is None else np.asarray(alternate_axis, float)
        self.alternate_every_s = float(alternate_every_s)
        self.speed_deg_s, self.wobble_deg = speed_deg_s, wobble_deg
        self.press = dict(DEFAULT_PRESS_M if press_depth_m is None else press_depth_m)
        for f in self.fingers:
            if not 0.0 < self.press.get(f, -1.0) <= MAX_PENETRATION_M:
                raise ValueError(
                    f"press depth of {f} must be in (0, {MAX_PENETRATION_M}] m, got {self.press.get(f)}"
                )
        self.period_s, self.contact_fraction = period_s, contact_fraction
        self._world_T_palm, self._world_T_camera = world_T_palm, world_T_camera
        self.seed = seed
        self.scene: SimScene | None = None

    # ------------------------------------------------------------------ set-up
    def open(self) -> None:
        if self.scene is not None:
            return
        # The natural grasp posture, from a scene-free model: it fixes the grasp centre, and
        # the centre fixes the default camera, which is part of the scene.
        hand = HandKinematics(self._world_T_palm)
        hand.sensor_poses(NOMINAL_Q)
        self.nominal = {f: self._gel(hand.model, hand.data, f) for f in FINGERS}
        palm = hand.world_T_palm
        self.centre = self._grasp_centre(palm)
        camera = self._world_T_camera
        self.world_T_camera = (
            front_left_camera_pose(self.centre) if camera is None else np.asarray(camera, float)
        )
        self.scene = SimScene(self.obj, palm, self.world_T_camera)
        self.ik = FingertipIK(self.scene.model, self.scene.data)
        self._probe = mujoco.MjData(self.scene.model)
        self._probe.qpos[:] = NOMINAL_Q
        self._probe_ik = FingertipIK(self.scene.model, self._probe, iterations=15)
        self.trajectory = ObjectTrajectory(
            self.centre,
            self.axis,
            self.speed_deg_s,
            wobble_deg=self.wobble_deg,
            seed=self.seed,
            alternate_axis=self.alternate_axis,
            alternate_every_s=self.alternate_every_s,
        )
        self.policy = GaitingPolicy(
            self.trajectory,
            self._sample_contact,
            {f: self.press[f] for f in self.fingers},
            period_s=self.period_s,
            contact_fraction=self.contact_fraction,
            seed=self.seed,
            home={f: NOMINAL_Q[4 * i : 4 * i + 4] for i, f in enumerate(FINGERS)},
        )
        self.q = REST_Q.copy()
        for f in self.fingers:
            i = FINGERS.index(f)
            self.q[4 * i : 4 * i + 4] = NOMINAL_Q[4 * i : 4 * i + 4]
        self._sliding: dict[str, int] = {}  # finger -> cycle in which it is touching
        self._sensor_sites = {f: self.scene.model.site(f"{f}_digit").id for f in FINGERS}
        self._ray_geoms = np.zeros(len(_GRID_RAYS), np.int32)
        self._ray_dist = np.zeros(len(_GRID_RAYS))
        model = self.scene.model
        self._finger_geoms = {
            f: [g for g in range(model.ngeom) if (model.geom(g).name or "").startswith(f"{f}_")]
            for f in FINGERS
        }
        self._touched: dict[str, deque] = {f: deque(maxlen=MEMORY) for f in FINGERS}
        self.flat_base = flat_base_share(self.obj.mesh) >= FLAT_BASE_SHARE
        self._libraries: dict[tuple[str, int], np.ndarray] = {}
        self._profiles: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}  # per segment
        self.scene.set_state(self.q, self.trajectory.pose(0.0))

    @staticmethod
    def _gel(
        model: mujoco.MjModel, data: mujoco.MjData, finger: str
    ) -> tuple[np.ndarray, np.ndarray]:
        sid = _gel_site(model, finger)
        return data.site_xpos[sid].copy(), data.site_xmat[sid].reshape(3, 3)[:, 2].copy()

    def _on_flat_base(self, normal: np.ndarray, world_T_object: np.ndarray) -> bool:
        """Does a world-frame surface normal face the object's own -z (its flat base)?"""
        return self.flat_base and float(normal @ -world_T_object[:3, 2]) > BOTTOM_COS

    def _grasp_centre(self, palm: np.ndarray) -> np.ndarray:
        """Between the middle finger's and the thumb's natural pads, clear of the palm.

        The object's lowest point must clear the palm face: its half extent along the palm
        normal if it only turns about that normal (else its bounding radius), plus wobble room.
        """
        up, across = palm[:3, 0], palm[:3, 1]
        axes = [self.axis] + ([] if self.alternate_axis is None else [self.alternate_axis])
        upright = all(abs(a @ up) > 0.99 * np.linalg.norm(a) for a in axes)
        verts = np.asarray(self.obj.mesh.vertices)
        half_up = float(np.abs(verts @ up).max()) if upright else self.obj.bounds_radius
        wobble_room = np.sin(np.deg2rad(self.wobble_deg)) * self.obj.bounds_radius
        middle = self.nominal["middle"][0]
        centre = 0.5 * (middle + self.nominal["thumb"][0])
        centre -= ((centre - middle) @ across) * across  # centred on the middle finger
        palm_face = palm[:3, 3] + PALM_FACE_X * up
        centre += GRASP_REACH_M * palm[:3, 2]
        lowest = PALM_CLEARANCE_M + half_up + wobble_room
        return centre + max(0.0, lowest - (centre - palm_face) @ up) * up

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
        """
        model, data = self.scene.model, self._probe
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
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
        postures = np.clip(postures, box[:, 0], box[:, 1])
        world_T_object = self.trajectory.pose(touchdown_s)
        self.scene.set_object_pose(world_T_object, data)
        centre = world_T_object[:3, 3]
        within = self.obj.bounds_radius + GEL_WIDTH_M + MAX_SHIFT_M
        press = self.press.get(finger, 0.0)
        firm = [(b.finger, b.posture) for b in busy if b.firm]
        touches = []
        for q in postures:
            data.qpos[joints] = q
            mujoco.mj_kinematics(model, data)
            gel, pad = self._gel(model, data, finger)
            to_centre = centre - gel
            if to_centre @ to_centre > within * within or to_centre @ pad <= 0.0:
                continue  # out of reach, or the pad faces away from the object
            reach = self._reach(finger, data, points=False)[0]
            deepest = reach.max()
            shift = press - deepest  # move along the pad by this to press by `press`
            rays = int(np.count_nonzero(reach >= deepest - press))
            if not -MAX_SHIFT_M < shift < MAX_SHIFT_M or rays < MIN_CONTACT_RAYS:
                continue
            splay = round(abs(q[0] - NOMINAL_Q[4 * i]) / 0.1)
            touches.append((-min(rays, GOOD_CONTACT_RAYS), splay, abs(shift), len(touches), q))
            if len(touches) >= ENOUGH_TOUCHES:
                break  # a wide object: plenty to choose from
        touches.sort(key=lambda c: c[:4])
        candidates, blocked = [], []
        for c in touches:  # clearance is the costlier test: best first, as many as needed
            data.qpos[joints] = c[-1]
            (candidates if self._clear_of(finger, firm) else blocked).append(c)
            if len(candidates) >= VERIFY_CANDIDATES:
                break
        if not candidates:
            if blocked:
                # Only the neighbours are in the way: claim the best blocked touch, so that
                # their next contacts leave room for it, and look there first next time.
                claim = min(blocked, key=lambda c: c[:4])[-1]
                self.policy.claims[finger] = claim
                self._touched[finger].append(claim)
            return None
        # Of the best few, prefer the touch that leaves the other fingers the room where
        # they touched lately (their claims and latest touches): on a narrow object a touch
        # in the wrong place shuts a neighbour out.
        others = [(b.finger, b.posture) for b in busy if not b.firm] + [
            (g, p) for g in self.fingers if g != finger for p in list(self._touched[g])[-RECENT:]
        ]
        head = candidates[:COMPAT_CANDIDATES]
        if others:
            for n, c in enumerate(head):
                data.qpos[joints] = c[-1]
                free = sum(self._gap_to(finger, g, p) >= FINGER_CLEARANCE_M for g, p in others)
                head[n] = (-round(4 * free / len(others)), *c)
            head.sort(key=lambda c: c[:5])
            head = [c[1:] for c in head]
        up = self.scene.world_T_palm[:3, 0]
        rest = [(g, REST_Q[self.ik.qpos_adr[g]]) for g in self.fingers if g != finger]
        for *_, q in (head + candidates[COMPAT_CANDIDATES:])[:VERIFY_CANDIDATES]:
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
        self._touched[finger].append(candidates[0][-1])  # nearly: look around there next time
        return None

    def _library(self, finger: str, segment: int = 0) -> np.ndarray:
        """Postures of the finger's SAMPLE_BOX whose gel comes near the object as it turns.

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
        if segment not in self._profiles:
            pose = self.trajectory.pose(self.trajectory.segment_start(segment))
            rel = np.asarray(self.obj.mesh.vertices) @ pose[:3, :3].T + pose[:3, 3] - self.centre
            height = rel @ axis
            radial = rel - np.outer(height, axis)
            u, v = perpendicular_basis(axis)
            az = np.floor((np.arctan2(radial @ v, radial @ u) + np.pi) / (2 * np.pi) * 24)
            hb = np.floor(height / PROFILE_BIN_M).astype(int)
            outer = np.zeros((hb.max() - hb.min() + 1, 24))
            cells = (hb - hb.min(), np.clip(az, 0, 23).astype(int))
            np.maximum.at(outer, cells, np.linalg.norm(radial, axis=1))
            self._profiles[segment] = (hb.min(), outer.min(axis=1), outer.max(axis=1))
        low, r_in, r_out = self._profiles[segment]
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
            rel = gel - self.centre
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
            point = self._probe_ik.gel_point(finger, _GRID[k])
            target = FingerTarget(point + move * pad, pad, _GRID[k])
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

    def _gap(self, data: mujoco.MjData, a: str, b: str, upto: float = 0.01) -> float:
        """Smallest signed distance between two fingers' links and DIGIT bodies (m, up to `upto`)."""
        gap = upto
        for ga in self._finger_geoms[a]:
            for gb in self._finger_geoms[b]:
                gap = min(gap, mujoco.mj_geomDistance(self.scene.model, data, ga, gb, upto, None))
        return gap

    # ------------------------------------------------------------------ per time step
    def _reach(
        self,
        finger: str,
        data: mujoco.MjData | None = None,
        normals: bool = False,
        points: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Per gel ray: reach of the object past the gel surface (m; -inf = miss), hit point, normal.

        Rays from the DIGIT's camera through a 5 x 5 grid on the gel, the renderer's own
        definition of depth (along the sensor's +z); hits within 10 cm. Hit points are in
        the world frame (None unless `points`); normals (outward, world) only when asked
        for, else None.
        """
        data = self.scene.data if data is None else data
        sid = self._sensor_sites[finger]
        rot = data.site_xmat[sid].reshape(3, 3)
        origin = data.site_xpos[sid].copy()
        directions = _GRID_RAYS @ rot.T
        mujoco.mj_multiRay(
            self.scene.model,
            data,
            origin,
            np.ascontiguousarray(directions.ravel()),
            self.scene.object_groups,
            1,
            -1,
            self._ray_geoms,
            self._ray_dist,
            None,
            len(_GRID_RAYS),
            0.1,
        )
        hit = self._ray_dist >= 0
        reach = np.where(hit, GEL_DISTANCE_M - self._ray_dist * _GRID_RAYS[:, 2], -np.inf)
        if not points:
            return reach, None, None
        points = origin + self._ray_dist[:, None] * directions
        found = None
        if normals:
            found = np.zeros((len(_GRID_RAYS), 3))
            for k in np.flatnonzero(hit):
                found[k] = self.scene.ray_object(origin, directions[k], data)[1]
        return reach, points, found

    def press_depth(self, finger: str) -> float:
        """Deepest reach of the object past the gel surface over the gel area (m; <= 0 = gap).

        Returns -_PROBE_BACK_M when nothing is in view within 10 cm.
        """
        deepest = float(self._reach(finger, points=False)[0].max())
        return deepest if np.isfinite(deepest) else -_PROBE_BACK_M

    def _touch_point(self, finger: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Surface point (world) the gel touches nearest its centre, and the normal there."""
        reach, points, _ = self._reach(finger)
        for k in _CENTRE_FIRST:
            if reach[k] > 0:
                sid = self._sensor_sites[finger]
                origin = self.scene.data.site_xpos[sid]
                direction = points[k] - origin
                normal = self.scene.ray_object(origin, direction / np.linalg.norm(direction))[1]
                return points[k], normal
        return None

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
                if plans[f].touching and press[f] <= -_PROBE_BACK_M + 1e-9:
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
                if press[f] > -_PROBE_BACK_M and before > -_PROBE_BACK_M:
                    gain[f] = float(np.clip((press[f] - before) / move, 0.3, 4.0))

    def state_at(self, t: float) -> RigState:
        if self.scene is None:
            self.open()
        world_T_object = self.trajectory.pose(t)
        self.scene.set_state(self.q, world_T_object)
        object_T_world = invert_pose(world_T_object)
        plans: dict[str, FingerPlan] = {}
        targets: dict[str, FingerTarget] = {}
        rot, trans = world_T_object[:3, :3], world_T_object[:3, 3]
        for f in sorted(self.fingers, key=PLAN_ORDER.index):
            gel, pad = self.nominal[f]
            hover = object_T_world[:3, :3] @ (gel - HOVER_BACK_M * pad) + object_T_world[:3, 3]
            plan = self.policy.plan(f, t, hover, object_T_world[:3, :3] @ pad)
            plans[f] = plan
            if plan.touching and self._sliding.get(f) == plan.cycle:
                # Already touching in this cycle: hold the finger where it is and let the
                # surface slide under it; press control below keeps the depth.
                targets[f] = FingerTarget(*self.ik.gel_pose(f))
            else:
                targets[f] = FingerTarget(rot @ plan.gel_target + trans, rot @ plan.pad_direction)
        errors = self.ik.solve(targets)
        for f, plan in plans.items():
            # A finger stuck in another IK branch restarts from the posture its contact came from.
            if (
                errors[f] > RETRY_IK_M
                and plan.contact is not None
                and plan.contact.posture is not None
            ):
                adr = self.ik.qpos_adr[f]
                before = self.scene.data.qpos[adr].copy()
                self.scene.data.qpos[adr] = plan.contact.posture
                retry = self.ik.solve({f: targets[f]})[f]
                if retry < errors[f]:
                    errors[f] = retry
                else:
                    self.scene.data.qpos[adr] = before
                    self.ik.forward()
        press = {f: self.press_depth(f) for f in self.fingers}
        self._press_control(self.fingers, plans, targets, errors, press)
        # A held finger whose touch slid off its gel (the object's wobble moves a touch on the
        # gel's edge sideways) follows the object for this step and presses again.
        slipped = {
            f: FingerTarget(rot @ plans[f].gel_target + trans, rot @ plans[f].pad_direction)
            for f in self.fingers
            if plans[f].touching and self._sliding.get(f) == plans[f].cycle and press[f] <= 0
        }
        if slipped:
            errors.update(self.ik.solve(slipped))
            targets.update(slipped)
            press.update({f: self.press_depth(f) for f in slipped})
            self._press_control(list(slipped), plans, targets, errors, press)
        for f in self._keep_apart(plans, self.q):
            errors[f] = float(np.linalg.norm(targets[f].gel_position - self.ik.gel_pose(f)[0]))
            press[f] = self.press_depth(f)
        touching, contact = {}, {}
        for f in self.fingers:
            plan = plans[f]
            hit = self._touch_point(f) if plan.touching else None
            ok = plan.touching and errors[f] < LOST_CONTACT_M and press[f] > 0 and hit is not None
            # a touch that slid onto the object's flat base gives up (see BOTTOM_COS)
            ok = ok and not self._on_flat_base(hit[1], world_T_object)
            if plan.touching and not ok:
                self.policy.broken.add((f, plan.cycle))
            touching[f] = ok
            contact[f] = None
            if ok:
                self._sliding[f] = plan.cycle
                point, normal = hit
                gel, pad = self.ik.gel_pose(f)
                rot_o, trans_o = object_T_world[:3, :3], object_T_world[:3, 3]
                contact[f] = rot_o @ point + trans_o
                # The lift starts from where the gel is now (backed off to zero press).
                self.policy.last_contact[(f, plan.cycle)] = Contact(
                    rot_o @ (gel - press[f] * pad) + trans_o, rot_o @ normal, rot_o @ pad
                )
        self.q = self.scene.data.qpos[:16].copy()
        self.scene.set_state(self.q, world_T_object)
        return RigState(
            time_s=t,
            joint_positions=self.q.copy(),
            world_T_object=world_T_object,
            world_T_sensor=self.scene.sensor_poses(),
            touching=touching,
            contact_point=contact,
            press_m=press,
            ik_error_m=errors,
        )
