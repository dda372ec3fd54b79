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

The tuning constants live in rig_params.py, the gel ray casts and finger gaps in
rig_probes.py, contact sampling in contact_sampler.py, press control and keeping the
fingers apart in finger_control.py (all three mixins of SimRig). With a TouchPlanner
(sensor.policy=active, touch_planner.py) new contacts go where the map's advice scores
highest, and the object is regrasped (turned and slid) when no reachable touch scores well.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from neuralfeels_sem.core.digit import MAX_PENETRATION_M
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.objects.proximity import closest_faces
from neuralfeels_sem.sim.camera_renderer import front_left_camera_pose
from neuralfeels_sem.sim.contact_sampler import ContactSampler
from neuralfeels_sem.sim.finger_control import FingerControl
from neuralfeels_sem.sim.hand_model import PALM_FACE_X
from neuralfeels_sem.sim.ik import FingerTarget, FingertipIK
from neuralfeels_sem.sim.kinematics import HandKinematics
from neuralfeels_sem.sim.policy import Contact, FingerPlan, GaitingPolicy
from neuralfeels_sem.sim.rig_params import (
    DEFAULT_PRESS_M,
    FLAT_BASE_SHARE,
    GRASP_REACH_M,
    HOVER_BACK_M,
    LOST_CONTACT_M,
    MEMORY,
    NOMINAL_Q,
    PALM_CLEARANCE_M,
    PLAN_ORDER,
    REST_Q,
    RETRY_IK_M,
    flat_base_share,
)
from neuralfeels_sem.sim.rig_probes import GEL_GRID_RAYS, RigProbes
from neuralfeels_sem.sim.scene import SimScene
from neuralfeels_sem.sim.touch_planner import TouchPlanner, check_turn_axes
from neuralfeels_sem.sim.trajectory import ObjectTrajectory, RestHeight, check_grasp_height


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


class SimRig(ContactSampler, FingerControl, RigProbes):
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
        planner: TouchPlanner | None = None,
        grasp_height: str = "fixed",
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
        self.planner = planner  # sensor.policy=active: touches ranked by the map's advice
        if planner is not None:
            check_turn_axes(planner.config.turn, alternate_axis)
        check_grasp_height(grasp_height)
        # fixed: the centre high enough for any orientation; follow: as low as each allows
        self.grasp_height = grasp_height
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
            rest=self._rest_height(palm),
        )
        self.regrasp_reasons: list[str] = []  # beside trajectory.regrasps: why each was due
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
        self._ray_geoms = np.zeros(len(GEL_GRID_RAYS), np.int32)
        self._ray_dist = np.zeros(len(GEL_GRID_RAYS))
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

    def _grasp_centre(self, palm: np.ndarray) -> np.ndarray:
        """Between the middle finger's and the thumb's natural pads, clear of the palm.

        The object's lowest point must clear the palm face: its half extent along the palm
        normal if it only turns about that normal (else its bounding radius), plus wobble
        room. With grasp_height=follow the centre stays at the pads' height and the
        trajectory lifts the object as each orientation needs (_rest_height).
        """
        up, across = palm[:3, 0], palm[:3, 1]
        middle = self.nominal["middle"][0]
        centre = 0.5 * (middle + self.nominal["thumb"][0])
        centre -= ((centre - middle) @ across) * across  # centred on the middle finger
        centre += GRASP_REACH_M * palm[:3, 2]
        if self.grasp_height == "follow":
            return centre
        axes = [self.axis] + ([] if self.alternate_axis is None else [self.alternate_axis])
        upright = all(abs(a @ up) > 0.99 * np.linalg.norm(a) for a in axes)
        verts = np.asarray(self.obj.mesh.vertices)
        half_up = float(np.abs(verts @ up).max()) if upright else self.obj.bounds_radius
        lowest = half_up + self._palm_room()
        return centre + max(0.0, lowest - (centre - self._palm_face(palm)) @ up) * up

    def _palm_face(self, palm: np.ndarray) -> np.ndarray:
        return palm[:3, 3] + PALM_FACE_X * palm[:3, 0]

    def _palm_room(self) -> float:
        """Clearance the object's lowest point keeps from the palm face, wobble included."""
        return PALM_CLEARANCE_M + np.sin(np.deg2rad(self.wobble_deg)) * self.obj.bounds_radius

    def _rest_height(self, palm: np.ndarray) -> RestHeight | None:
        """grasp_height=follow: the lift that keeps each orientation's lowest point clear."""
        if self.grasp_height != "follow":
            return None
        room = float((self.centre - self._palm_face(palm)) @ palm[:3, 0]) - self._palm_room()
        hull = np.asarray(self.obj.mesh.convex_hull.vertices)
        return RestHeight(hull, palm[:3, 0], room)

    def _regrasp(self, t: float) -> None:
        """Turn and slide the object in the grasp as the planner asks (sensor.policy=active).

        The new stretch starts at t or the latest time already planned for; the finger
        libraries and swept profiles of the stretches it replaces are dropped.
        """
        start = max(t, self.trajectory.horizon_s)
        move = self.planner.regrasp_move(
            self.trajectory.pose(start), self.scene.world_T_palm[:3, 0]
        )
        if move is None:
            return
        k, _ = self.trajectory.regrasp(start, *move)
        self._new_stretch(k)

    def _consider_turn(self, points: np.ndarray, touchdown_s: float) -> None:
        """sensor.planner.turn=advice or advance: note where the finger could press (the screened
        touches' object-frame points) and, when a comparison is due, turn the object the
        way that brings the fingers the most touch score (sim/turn_choice.py)."""
        turns = self.planner.turns
        if turns is None:
            return
        pose = self.trajectory.pose(touchdown_s)
        normals = None
        if turns.facing_cos is not None:  # the surface each screened touch meets
            faces, _ = closest_faces(self.obj.mesh, points)
            normals = self.obj.mesh.face_normals[faces] @ pose[:3, :3].T
        turns.note_reach(points @ pose[:3, :3].T + pose[:3, 3], normals, points)
        if not self.planner.turn_due(touchdown_s):
            return
        start = max(touchdown_s, self.trajectory.horizon_s)
        plan = self.trajectory.steady_poses(start + turns.ahead)
        advance = self.planner.config.turn == "advance"  # only the gait's next stretch
        axes = [self.trajectory.next_axis(start)] if advance else turns.candidates
        options = [self.trajectory.turn_poses(start, a, turns.ahead) for a in axes]
        axis = self.planner.choose_turn(touchdown_s, plan, options, axes)
        if axis is not None:
            k, _ = self.trajectory.turn(start, axis)
            self._new_stretch(k)

    def _new_stretch(self, k: int) -> None:
        """A regrasp or turn started segment k: drop what was built for the ones it replaced."""
        self.regrasp_reasons.append(self.planner.due_reason)
        self._libraries = {key: v for key, v in self._libraries.items() if key[1] < k}
        self._profiles = {s: v for s, v in self._profiles.items() if s < k}

    def state_at(self, t: float) -> RigState:
        if self.scene is None:
            self.open()
        world_T_object = self.trajectory.pose(t)
        self.scene.set_state(self.q, world_T_object)
        object_T_world = invert_pose(world_T_object)
        plans, targets = self._plan(t, world_T_object, object_T_world)
        errors = self.ik.solve(targets)
        self._retry_stuck(plans, targets, errors)
        press = {f: self.press_depth(f) for f in self.fingers}
        self._press_control(self.fingers, plans, targets, errors, press)
        self._follow_slipped(plans, targets, errors, press, world_T_object)
        for f in self._keep_apart(plans, self.q):
            errors[f] = float(np.linalg.norm(targets[f].gel_position - self.ik.gel_pose(f)[0]))
            press[f] = self.press_depth(f)
        self._back_out(plans, targets, errors, press)
        touching, contact = self._record_contacts(
            plans, errors, press, world_T_object, object_T_world
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

    def _plan(
        self, t: float, world_T_object: np.ndarray, object_T_world: np.ndarray
    ) -> tuple[dict[str, FingerPlan], dict[str, FingerTarget]]:
        """Every finger's plan from the policy (in PLAN_ORDER) and its world-frame IK target."""
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
        return plans, targets

    def _retry_stuck(
        self,
        plans: dict[str, FingerPlan],
        targets: dict[str, FingerTarget],
        errors: dict[str, float],
    ) -> None:
        """A finger stuck in another IK branch restarts from the posture its contact came from."""
        for f, plan in plans.items():
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

    def _follow_slipped(
        self,
        plans: dict[str, FingerPlan],
        targets: dict[str, FingerTarget],
        errors: dict[str, float],
        press: dict[str, float],
        world_T_object: np.ndarray,
    ) -> None:
        """A held finger whose touch slid off its gel follows the object and presses again.

        The object's wobble moves a touch on the gel's edge sideways; such a finger follows
        the object for this step. Updates targets, errors and press in place.
        """
        rot, trans = world_T_object[:3, :3], world_T_object[:3, 3]
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

    def _record_contacts(
        self,
        plans: dict[str, FingerPlan],
        errors: dict[str, float],
        press: dict[str, float],
        world_T_object: np.ndarray,
        object_T_world: np.ndarray,
    ) -> tuple[dict[str, bool], dict[str, np.ndarray | None]]:
        """Which fingers touch and where (object frame); tells the policy of made and broken touches."""
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
        return touching, contact
