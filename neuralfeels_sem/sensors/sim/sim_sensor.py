"""SimSensor: Frames from the simulated rig, with full ground truth.

Per frame (time index / fps): the rig (sim/rig.py) turns the object and places the
fingers, each configured DIGIT is rendered at its fingertip pose, and the camera
renders RGB-D with the hand's links as occluders. Each finger's renderer is seeded
with `seed + finger index`, so a finger keeps its own background (like a physical
sensor) and task=collect_tactile, which uses the same seeds, trains the classifier on
the same sensors a run sees.

`policy=active`: new contacts go where the map is most uncertain (sim/touch_planner.py).
The mapping session's touch advisor (pipeline/touch_advisor.py) hands the sensor its
advice after every mapped frame (`advise`); at sensor.pace=offline frame j is planned
with the advice of frame j - `advice_lag_frames` (1: the newest the mapper can have).
Frames are rendered as the session asks for them, so a touch chosen at time t shapes the
frames after t; a producer that renders ahead of the mapper waits for the advice it needs
(up to ADVICE_WAIT_S), so the same seed gives the same run. A lag above 1 lets the
producer render that many frames ahead, the touches planned on a slightly older map.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import Frame, TactileReading
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sensors.base import IndexedSensor, check_pace
from neuralfeels_sem.sim.backgrounds import finger_seed

DEFAULT_FIRMNESS_MM = {"index": 1.5, "middle": 1.5, "ring": 1.5, "thumb": 0.7}
POLICIES = ("scripted", "active")
ADVICE_WAIT_S = 600.0  # longest a frame waits for the advice of the frame before it

log = logging.getLogger(__name__)


class SimSensor(IndexedSensor):
    """The simulated rig. Construction stores arguments; `open()` builds scene and renderers.

    Args:
        obj: the object (the task passes the instantiated cfg.object).
        class_names: the run's material classes; must equal obj.class_names.
        duration_s, fps: run length and frame rate (sensor time).
        fingers: DIGITs to render (the others stay bent back, out of the way).
        camera: render the RGB-D camera.
        rotation_axis, rotation_speed_deg_s, wobble_deg: the object's motion.
        alternate_axis, alternate_every_s: the object turns about rotation_axis and
            alternate_axis in turn, alternate_every_s seconds each (None: one axis).
        grasp_height: fixed | follow, how high the object sits above the palm (SimRig).
        gait_period_s, contact_fraction: finger gaiting cycle.
        firmness_mm: press depth per finger (thumb weaker by default, as in the paper).
        tactile: DigitRenderer options (background, noise_std, texture_scale, ...).
        rgbd: camera options (width, height, fov_y_deg, depth_noise, realsense, distance)
            and the lab scenery (table_height, backdrop_distance, mount).
        policy: scripted (the gait's sampled touches) or active (the map's advice ranks them).
        planner: TouchPlannerConfig options for policy=active.
        advice_lag_frames: policy=active, offline: frame j follows frame j - this's advice.
        pace: offline | realtime (sensors/base.py PACES), read by a mapping run.
    """

    def __init__(
        self,
        obj: MaterialObject | None = None,
        class_names: Sequence[str] | None = None,
        name: str = "sim",
        duration_s: float = 20.0,
        fps: float = 10.0,
        fingers: Sequence[str] = FINGERS,
        camera: bool = True,
        rotation_axis: Sequence[float] = (0.0, 0.0, 1.0),
        rotation_speed_deg_s: float = 30.0,
        wobble_deg: float = 4.0,
        alternate_axis: Sequence[float] | None = (0.0, 1.0, 0.0),
        alternate_every_s: float = 5.0,
        grasp_height: str = "fixed",
        gait_period_s: float = 1.2,
        contact_fraction: float = 0.75,
        firmness_mm: dict[str, float] | None = None,
        seed: int = 0,
        tactile: dict | None = None,
        rgbd: dict | None = None,
        policy: str = "scripted",
        planner: dict | None = None,
        pace: str = "offline",
        advice_lag_frames: int = 1,
    ) -> None:
        if duration_s <= 0 or fps <= 0:
            raise ValueError(f"duration_s and fps must be > 0, got {duration_s}, {fps}")
        if policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
        self.policy, self.planner_options = policy, dict(planner or {})
        self._init_advice(advice_lag_frames)
        self.obj = obj
        self.class_names = None if class_names is None else tuple(class_names)
        self.name = name
        self.duration_s, self.fps = float(duration_s), float(fps)
        self.frame_period_s = 1.0 / self.fps
        self.fingers = tuple(f for f in FINGERS if f in fingers)
        unknown = set(fingers) - set(FINGERS)
        if unknown or not self.fingers:
            raise ValueError(
                f"fingers must be a non-empty subset of {FINGERS}, got {list(fingers)}"
            )
        self.camera_enabled = bool(camera)
        self.rotation_axis = tuple(float(v) for v in rotation_axis)
        self.rotation_speed, self.wobble_deg = float(rotation_speed_deg_s), float(wobble_deg)
        self.alternate_axis = None if alternate_axis is None else tuple(map(float, alternate_axis))
        self.alternate_every_s = float(alternate_every_s)
        self.grasp_height = grasp_height
        self.gait_period_s, self.contact_fraction = float(gait_period_s), float(contact_fraction)
        firmness = dict(DEFAULT_FIRMNESS_MM)
        firmness.update(firmness_mm or {})
        self.firmness_mm = firmness
        self.seed = int(seed)
        self.tactile_options = dict(tactile or {})
        self.rgbd_options = dict(rgbd or {})
        self.pace = check_pace(pace)
        self.rig = None
        self.renderers: dict = {}
        self.camera_renderer = None

    def __len__(self) -> int:
        return int(np.floor(self.duration_s * self.fps + 1e-9))

    def open(self) -> None:
        if self.rig is not None:
            return
        from neuralfeels_sem.sim.rig import SimRig
        from neuralfeels_sem.sim.tactile_renderer import DigitRenderer
        from neuralfeels_sem.sim.touch_planner import TouchPlanner, TouchPlannerConfig

        if self.obj is None:
            raise ConfigError(
                "sensor=sim needs an object: pick one with object=<name> (see conf/object/)"
            )
        if self.class_names is not None and tuple(self.obj.class_names) != self.class_names:
            raise ConfigError(
                f"object {self.obj.name!r} is labelled with {list(self.obj.class_names)} but materials="
                f"{list(self.class_names)}: build the object with class_names=${{materials}}"
            )
        self.rig = SimRig(
            self.obj,
            fingers=self.fingers,
            axis=self.rotation_axis,
            speed_deg_s=self.rotation_speed,
            wobble_deg=self.wobble_deg,
            alternate_axis=self.alternate_axis,
            alternate_every_s=self.alternate_every_s,
            grasp_height=self.grasp_height,
            press_depth_m={f: v / 1000.0 for f, v in self.firmness_mm.items()},
            period_s=self.gait_period_s,
            contact_fraction=self.contact_fraction,
            seed=self.seed,
            planner=TouchPlanner(TouchPlannerConfig(**self.planner_options))
            if self.accepts_advice
            else None,
        )
        self.rig.open()
        self.renderers = {
            f: DigitRenderer(self.obj, seed=finger_seed(self.seed, f), **self.tactile_options)
            for f in self.fingers
        }
        if self.camera_enabled:
            self.camera_renderer = self._camera_renderer()

    def _camera_renderer(self):
        """The RGB-D camera at `distance` from the grasp centre, with the lab scenery around."""
        from neuralfeels_sem.sim.camera_renderer import CameraRenderer, front_left_camera_pose
        from neuralfeels_sem.sim.lab_scenery import backdrop, hand_mount

        options = dict(self.rgbd_options)
        distance = float(options.pop("distance", 0.35))
        backdrop_distance = options.pop("backdrop_distance", None)
        mount = bool(options.pop("mount", False))
        world_T_camera = front_left_camera_pose(self.rig.centre, distance)
        scenery = [] if backdrop_distance is None else [backdrop(world_T_camera, backdrop_distance)]
        if mount:
            scenery.append(hand_mount(self.rig.scene.world_T_palm))
        return CameraRenderer(
            self.obj, world_T_camera=world_T_camera, seed=self.seed, scenery=scenery, **options
        )

    def hand_model(self):
        """The hand's kinematics at the rig's palm pose (a scene-free model, not the MuJoCo
        scene's own geoms): what a rig knows of its hand from its description."""
        from neuralfeels_sem.sim.kinematics import HandKinematics

        self.open()
        return HandKinematics(self.rig.scene.world_T_palm)

    @property
    def accepts_advice(self) -> bool:
        """Whether the touches follow the map's advice (policy=active)."""
        return self.policy == "active"

    @property
    def confirm_regrasps(self) -> bool:
        """Whether the planner regrasps for readings to confirm (its confirm_regrasp_after)."""
        return self.accepts_advice and self.planner_options.get("confirm_regrasp_after") is not None

    def _init_advice(self, lag: int) -> None:
        """No advice yet; frame j will follow frame j - lag's (policy=active, offline)."""
        if lag < 1:
            raise ValueError(f"advice_lag_frames must be >= 1, got {lag}")
        self.advice_lag = int(lag)
        self._advice, self._advice_index = None, -1
        self._advices: dict[int, object] = {}  # the latest advice_lag ones, by frame index
        self._first_index: int | None = None  # the first frame asked for (a resumed run's)
        self._advice_ready = threading.Condition()

    def advise(self, frame_index: int, advice) -> None:
        """The map's TouchAdvice after mapping `frame_index` (sim/touch_advice.py)."""
        with self._advice_ready:
            self._advice, self._advice_index = advice, int(frame_index)
            self._advices[int(frame_index)] = advice
            for old in [k for k in self._advices if k <= frame_index - self.advice_lag]:
                del self._advices[old]  # every frame still to come needs a later one
            self._advice_ready.notify_all()

    def _latest_advice(self, index: int):
        """The advice frame `index` is planned with: frame index - lag's, once advice flows.

        Before the first advice (frame 0, or the frames a resumed run skips) there is none;
        at sensor.pace=realtime it is the newest advice, whatever frame it follows.
        """
        with self._advice_ready:
            if getattr(self, "pace", "offline") != "offline":
                return self._advice
            wanted = index - self.advice_lag
            if self._first_index is None:
                self._first_index = index  # advice comes for this frame and later ones
            # Further behind than one frame, wait for any frame the run maps (a frame rendered
            # ahead must not take whichever advice came last). One frame behind, wait once
            # advice flows: the frames rendered while the first frame is mapped (its warm-up)
            # go without, the same ones in every run (a run repeated under another load maps
            # to the last digit). Waiting for the first frame's advice too, as longer lags
            # do, was measured side by side (oracle: object pose) and is no better: shipped
            # objects (patched_toy, patchwork, kitchen_tool, seeds 0-3) 3 of 12 runs changed,
            # means within 0.1 point, time to 90 % 0.94 of the gait's in both; development
            # objects (seeds 0-1) 8 of 18 changed, 90.3 against 91.1 % mean-class; the
            # default run 97.7 against 91.6 %.
            due = self._advice_index >= 0 if self.advice_lag == 1 else wanted >= self._first_index
            if due and not self._advice_ready.wait_for(
                lambda: self._advice_index >= wanted, timeout=ADVICE_WAIT_S
            ):
                log.warning("frame %d planned without the advice of frame %d", index, wanted)
                return self._advice
            return self._advices.get(wanted)  # lag 1: the newest (no later frame is mapped)

    def touch_plan(self) -> dict | None:
        """What the active policy did: its choices and regrasps (None for policy=scripted)."""
        if self.rig is None or self.rig.planner is None:
            return None
        planner, trajectory = self.rig.planner, self.rig.trajectory
        scores = [c[2] for c in planner.choices]
        return {
            "policy": self.policy,
            "choices": len(scores),
            "mean_best_score": float(np.mean(scores)) if scores else None,
            "regrasps": [
                {"time_s": t, "axis": axis.tolist(), "offset_m": offset.tolist(), "why": why}
                for (t, axis, offset), why in zip(trajectory.regrasps, self.rig.regrasp_reasons)
            ],
            # turn=advice or advance: each comparison of the plan with the best turn
            # (sim/turn_choice.py)
            "turn_checks": [
                {"time_s": t, "plan_gain": kept, "best_gain": best, "axis": axis}
                for t, kept, best, axis in (planner.turns.log if planner.turns else [])
            ],
        }

    def close(self) -> None:
        for renderer in self.renderers.values():
            renderer.close()
        if self.camera_renderer is not None:
            self.camera_renderer.close()
        self.renderers, self.camera_renderer, self.rig = {}, None, None

    def frame_at(self, index: int, touches_only: bool = False) -> Frame:
        """Frame `index` (call with non-decreasing indices: the fingers move incrementally);
        `touches_only`: the DIGITs' readings without the camera's (Frame.touches_only)."""
        self.open()
        t = index / self.fps
        if self.rig.planner is not None:
            self.rig.planner.advice = self._latest_advice(index)
        state = self.rig.state_at(t)
        tactile = {}
        for finger, renderer in self.renderers.items():
            world_T_sensor = state.world_T_sensor[finger]
            render = renderer.render(state.world_T_object, world_T_sensor)
            tactile[finger] = TactileReading(
                finger=finger,
                image=render.image,
                world_T_sensor=world_T_sensor,
                intrinsics=DIGIT_INTRINSICS,
                background=renderer.background_image,
                gt_contact_mask=render.contact_mask,
                gt_depth=render.depth,
                gt_material=render.material,
            )
        camera = None
        if self.camera_renderer is not None and not touches_only:
            camera = self.camera_renderer.render(
                state.world_T_object, occluders=self.rig.scene.hand_meshes()
            )
        return Frame(
            index=index,
            time_s=t,
            world_T_object=state.world_T_object.copy(),
            tactile=tactile,
            camera=camera,
            gt_world_T_object=state.world_T_object.copy(),
            joint_positions=state.joint_positions,
            touches_only=touches_only,
        )
