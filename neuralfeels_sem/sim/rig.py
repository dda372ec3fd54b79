"""The simulated rig over time: object trajectory + gaiting policy + IK + press control on the MuJoCo scene.

`SimRig.state_at(t)` (t non-decreasing) moves the object's mocap body along its
trajectory, asks the policy for every finger's target, solves IK for the joint angles
and corrects each finger along its pad direction so that the object reaches into the
gel by the finger's firmness (measured with ray casts over the gel area: a finger
whose pad cannot lie flat on the surface still presses by that depth at its deepest
point). The result is written to qpos and the scene is forwarded (mj_forward).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sensors.frame import FINGERS
from neuralfeels_sem.sim.camera_renderer import front_left_camera_pose
from neuralfeels_sem.sim.digit_geometry import (
    GEL_DISTANCE_M,
    GEL_HEIGHT_M,
    GEL_WIDTH_M,
    MAX_PENETRATION_M,
)
from neuralfeels_sem.sim.hand_model import PALM_FACE_X
from neuralfeels_sem.sim.ik import FingerTarget, FingertipIK
from neuralfeels_sem.sim.kinematics import HandKinematics
from neuralfeels_sem.sim.policy import Contact, FingerPlan, GaitingPolicy
from neuralfeels_sem.sim.scene import SimScene
from neuralfeels_sem.sim.trajectory import ObjectTrajectory
from neuralfeels_sem.utils.geometry import invert_pose

DEFAULT_PRESS_M = {"index": 0.0015, "middle": 0.0015, "ring": 0.0015, "thumb": 0.0007}
# Posture of fingers that take no part (bent back, away from the object) and the IK start.
REST_Q = np.array([0.0, -0.19, 0.0, 0.0] * 3 + [0.263, 0.0, 0.0, 0.0])
# Natural grasp posture (pads of fingers and thumb face each other; index and ring turned in
# toward the middle finger) and how far contact postures are sampled around it, per joint.
NOMINAL_Q = np.array(
    [0.4, 0.6, 0.6, 0.5, 0.0, 0.6, 0.6, 0.5, -0.4, 0.6, 0.6, 0.5, 1.25, 0.1, 0.3, 0.3]
)
POSTURE_JITTER = np.array([0.2, 0.3, 0.3, 0.3] * 3 + [0.12, 0.25, 0.25, 0.25])
SAMPLE_TRIES = 24
VERIFY_CANDIDATES = 6  # closest sampled touches checked for reachability by IK
RAY_BACK_M = 0.06  # contact rays start this far behind the gel surface
MAX_SHIFT_M = 0.015  # a sampled pad may be at most this far from the surface
GRAZING_COS = 0.5  # the surface must face the pad within 60 degrees
HOVER_BACK_M = 0.015  # a finger with nothing to touch waits this far behind its natural place
PALM_CLEARANCE_M = 0.008
RETRY_IK_M = 0.001  # IK error above which a finger retries from its contact's posture
LOST_CONTACT_M = 0.003  # a touching finger further than this from its target gives up the contact
_GRID = np.stack(
    np.meshgrid(
        np.linspace(-0.45, 0.45, 5) * GEL_WIDTH_M, np.linspace(-0.45, 0.45, 5) * GEL_HEIGHT_M
    ),
    -1,
).reshape(-1, 2)
_PROBE_BACK_M = 0.01  # centre probes start this far behind the gel surface
# Unit rays from the DIGIT camera through the grid points on the gel (sensor frame).
_GRID_RAYS = np.column_stack([_GRID, np.full(len(_GRID), GEL_DISTANCE_M)])
_GRID_RAYS /= np.linalg.norm(_GRID_RAYS, axis=1, keepdims=True)


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
    ) -> None:
        unknown = set(fingers) - set(FINGERS)
        if unknown or not fingers:
            raise ValueError(
                f"fingers must be a non-empty subset of {FINGERS}, got {list(fingers)}"
            )
        self.obj = obj
        self.fingers = tuple(f for f in FINGERS if f in fingers)
        self.axis = np.asarray(axis, np.float64)
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
        self._probe_ik = FingertipIK(self.scene.model, self._probe, iterations=30)
        self.trajectory = ObjectTrajectory(
            self.centre, self.axis, self.speed_deg_s, wobble_deg=self.wobble_deg, seed=self.seed
        )
        self.policy = GaitingPolicy(
            self.trajectory,
            self._sample_contact,
            {f: self.press[f] for f in self.fingers},
            period_s=self.period_s,
            contact_fraction=self.contact_fraction,
            seed=self.seed,
        )
        self.q = REST_Q.copy()
        for f in self.fingers:
            i = FINGERS.index(f)
            self.q[4 * i : 4 * i + 4] = NOMINAL_Q[4 * i : 4 * i + 4]
        self._sliding: dict[str, int] = {}  # finger -> cycle in which it is touching
        self._sensor_sites = {f: self.scene.model.site(f"{f}_digit").id for f in FINGERS}
        self._ray_geoms = np.zeros(len(_GRID_RAYS), np.int32)
        self._ray_dist = np.zeros(len(_GRID_RAYS))
        self.scene.set_state(self.q, self.trajectory.pose(0.0))

    @staticmethod
    def _gel(
        model: mujoco.MjModel, data: mujoco.MjData, finger: str
    ) -> tuple[np.ndarray, np.ndarray]:
        sid = model.site(f"{finger}_gel").id
        return data.site_xpos[sid].copy(), data.site_xmat[sid].reshape(3, 3)[:, 2].copy()

    def _grasp_centre(self, palm: np.ndarray) -> np.ndarray:
        """Between the middle finger's and the thumb's natural pads, clear of the palm.

        The object's lowest point must clear the palm face: its half extent along the palm
        normal if it turns about that normal (else its bounding radius), plus wobble room.
        """
        up, across = palm[:3, 0], palm[:3, 1]
        axis = self.axis / np.linalg.norm(self.axis)
        verts = np.asarray(self.obj.mesh.vertices)
        half_up = (
            float(np.abs(verts @ up).max()) if abs(axis @ up) > 0.99 else self.obj.bounds_radius
        )
        wobble_room = np.sin(np.deg2rad(self.wobble_deg)) * self.obj.bounds_radius
        middle = self.nominal["middle"][0]
        centre = 0.5 * (middle + self.nominal["thumb"][0])
        centre -= ((centre - middle) @ across) * across  # centred on the middle finger
        palm_face = palm[:3, 3] + PALM_FACE_X * up
        lowest = PALM_CLEARANCE_M + half_up + wobble_room
        return centre + max(0.0, lowest - (centre - palm_face) @ up) * up

    def _sample_contact(
        self, finger: str, world_T_object: np.ndarray, rng: np.random.Generator
    ) -> Contact | None:
        """A reachable touch: a random posture near the natural one, its pad pushed onto the object.

        Touches within MAX_SHIFT_M of a sampled posture are preferred; a narrow or offset
        object that no finger posture nearly touches gets a second, wider search.
        """
        for max_shift in (MAX_SHIFT_M, 2.0 * MAX_SHIFT_M):
            contact = self._search_contact(finger, world_T_object, rng, max_shift)
            if contact is not None:
                return contact
        return None

    def _search_contact(
        self, finger: str, world_T_object: np.ndarray, rng: np.random.Generator, max_shift: float
    ) -> Contact | None:
        model, data = self.scene.model, self._probe
        self.scene.set_object_pose(world_T_object, data)
        i = FINGERS.index(finger)
        joints = slice(4 * i, 4 * i + 4)
        limits = self.ik.limits[finger]
        centre = world_T_object[:3, 3]
        candidates = []
        for _ in range(SAMPLE_TRIES):
            q = np.clip(
                NOMINAL_Q[joints] + rng.uniform(-1.0, 1.0, 4) * POSTURE_JITTER[joints],
                limits[:, 0],
                limits[:, 1],
            )
            data.qpos[joints] = q
            mujoco.mj_kinematics(model, data)
            gel, pad = self._gel(model, data, finger)
            # Look along the pad first; a narrow object may pass beside it, so then look
            # from the gel toward the object's centre (the IK tilts the finger the rest).
            to_centre = centre - gel
            to_centre /= np.linalg.norm(to_centre)
            for look in (pad, to_centre):
                start = gel - RAY_BACK_M * look
                dist, normal = self.scene.ray_object(start, look, data)
                shift = abs(dist - RAY_BACK_M)
                if dist >= 0 and shift < max_shift and normal @ pad <= -GRAZING_COS:
                    candidates.append((shift, q, start + dist * look, normal, pad))
        # The touch closest to its sampled posture that the IK reaches from there wins.
        candidates.sort(key=lambda c: c[0])
        for _, q, point, normal, pad in candidates[:VERIFY_CANDIDATES]:
            data.qpos[joints] = q
            target = FingerTarget(point + self.press.get(finger, 0.0) * pad, pad)
            if self._probe_ik.solve({finger: target})[finger] < 1e-3:
                object_T_world = invert_pose(world_T_object)
                rot = object_T_world[:3, :3]
                return Contact(
                    point=rot @ point + object_T_world[:3, 3],
                    normal=rot @ normal,
                    pad=rot @ pad,
                    posture=q.copy(),
                )
        return None

    # ------------------------------------------------------------------ per time step
    def press_depth(self, finger: str) -> float:
        """Deepest reach of the object past the gel surface over the gel area (m; <= 0 = gap).

        Rays from the DIGIT's camera through a 5 x 5 grid on the gel, the renderer's own
        definition of depth (along the sensor's +z). Returns -_PROBE_BACK_M when nothing is
        in view within 10 cm.
        """
        sid = self._sensor_sites[finger]
        rot = self.scene.data.site_xmat[sid].reshape(3, 3)
        directions = np.ascontiguousarray((_GRID_RAYS @ rot.T).ravel())
        mujoco.mj_multiRay(
            self.scene.model,
            self.scene.data,
            self.scene.data.site_xpos[sid].copy(),
            directions,
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
        if not hit.any():
            return -_PROBE_BACK_M
        depth = self._ray_dist[hit] * _GRID_RAYS[hit, 2]  # along +z of the sensor
        return float(GEL_DISTANCE_M - depth.min())

    def _centre_hit(self, finger: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Object surface point (world) in front of the gel centre along the pad, and its normal."""
        pos, pad = self.ik.gel_pose(finger)
        start = pos - _PROBE_BACK_M * pad
        dist, normal = self.scene.ray_object(start, pad)
        return None if dist < 0 else (start + dist * pad, normal)

    def state_at(self, t: float) -> RigState:
        if self.scene is None:
            self.open()
        world_T_object = self.trajectory.pose(t)
        # Cast new contacts against the object where it is at touch-down: the policy asks
        # through _cast_object_frame, which maps its rays through the current pose.
        self.scene.set_state(self.q, world_T_object)
        object_T_world = invert_pose(world_T_object)
        plans: dict[str, FingerPlan] = {}
        targets: dict[str, FingerTarget] = {}
        rot, trans = world_T_object[:3, :3], world_T_object[:3, 3]
        for f in self.fingers:
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
        for _ in range(2):  # press control: slide each finger along its pad direction
            shifted = {}
            for f in self.fingers:
                goal = self.press[f]
                delta = press[f] - goal if plans[f].touching else max(0.0, press[f] - goal)
                if plans[f].touching and press[f] <= -_PROBE_BACK_M + 1e-9:
                    continue  # nothing under the gel: IK error decides below
                if abs(delta) > 1e-4:
                    _, pad = self.ik.gel_pose(f)
                    shifted[f] = FingerTarget(
                        targets[f].gel_position - delta * pad, targets[f].pad_direction
                    )
            if not shifted:
                break
            errors.update(self.ik.solve(shifted))
            targets.update(shifted)
            press.update({f: self.press_depth(f) for f in shifted})
        touching, contact = {}, {}
        for f in self.fingers:
            plan = plans[f]
            hit = self._centre_hit(f) if plan.touching else None
            ok = plan.touching and errors[f] < LOST_CONTACT_M and press[f] > 0 and hit is not None
            if plan.touching and not ok:
                self.policy.broken.add((f, plan.cycle))
            touching[f] = ok
            contact[f] = None
            if ok:
                self._sliding[f] = plan.cycle
                point, normal = hit
                _, pad = self.ik.gel_pose(f)
                rot_o = object_T_world[:3, :3]
                contact[f] = rot_o @ point + object_T_world[:3, 3]
                self.policy.last_contact[(f, plan.cycle)] = Contact(
                    contact[f], rot_o @ normal, rot_o @ pad
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
