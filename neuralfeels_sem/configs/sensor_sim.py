"""Schemas for sensor=sim (the simulated rig) and task=collect_tactile (sim or real DIGITs)."""

from __future__ import annotations

from dataclasses import dataclass, field

from neuralfeels_sem.configs.object import TACTILE_DATA_OBJECTS
from neuralfeels_sem.core.digit import MAX_PENETRATION_M
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.limits import check_duration, check_rate
from neuralfeels_sem.sensors.base import check_pace
from neuralfeels_sem.sensors.sim.sim_sensor import POLICIES
from neuralfeels_sem.sim.depth_noise import DEPTH_NOISE_MODELS, RealSenseNoiseConfig
from neuralfeels_sem.sim.felt_material import check_ignored_faces
from neuralfeels_sem.sim.touch_planner import TouchPlannerConfig, check_turn_axes
from neuralfeels_sem.sim.trajectory import check_grasp_height


def _check_firmness(name: str, firmness: dict[str, float]) -> None:
    for finger, mm in firmness.items():
        if finger not in FINGERS:
            raise ValueError(f"{name}: unknown finger {finger!r}; use {', '.join(FINGERS)}")
        if not 0.0 < mm <= MAX_PENETRATION_M * 1000:
            raise ValueError(f"{name}.{finger}={mm} must be in (0, {MAX_PENETRATION_M * 1000}] mm")


@dataclass
class SimTactileConfig:
    """Options of each DIGIT renderer (sim/tactile_renderer.py)."""

    background: str | None = None  # null: procedural; or an empty DIGIT frame / a folder of them
    noise_std: float = 2.0  # grey levels
    texture_scale: float = 1.0  # 0 = smooth materials
    # What the gel feels on faces scoring ignores (seams, the face an object rests on):
    # nearest = the nearest labelled face's material (sim/felt_material.py); generic = a
    # texture of no material, which no real object has (runs before 2026-11-30).
    ignored_faces: str = "nearest"

    def __post_init__(self) -> None:
        if self.noise_std < 0 or self.texture_scale < 0:
            raise ValueError(
                f"sensor.tactile: noise_std={self.noise_std} and texture_scale={self.texture_scale} must be >= 0"
            )
        check_ignored_faces(self.ignored_faces)


@dataclass
class SimRgbdConfig:
    """The front-left RGB-D camera (sim/camera_renderer.py) and the lab it sees (sim/lab_scenery.py)."""

    width: int = 320
    height: int = 240
    fov_y_deg: float = 50.0
    depth_noise: str = "realsense"  # realsense (sim/depth_noise.py) | none (exact depth: an oracle)
    realsense: RealSenseNoiseConfig = field(default_factory=RealSenseNoiseConfig)
    distance: float = 0.35  # from the grasp centre
    table_height: float | None = (
        0.0  # world z of the table top (the palm is 15 cm above); null: none
    )
    backdrop_distance: float | None = 0.8  # wall, metres from the camera (level); null: none
    mount: bool = True  # the wrist and arm end behind the palm

    def __post_init__(self) -> None:
        if self.width < 16 or self.height < 16:
            raise ValueError(f"sensor.rgbd: {self.width}x{self.height} must be at least 16x16")
        if not 1.0 < self.fov_y_deg < 170.0:
            raise ValueError(f"sensor.rgbd.fov_y_deg={self.fov_y_deg} must be in (1, 170)")
        if self.depth_noise not in DEPTH_NOISE_MODELS:
            raise ValueError(
                f"sensor.rgbd.depth_noise={self.depth_noise!r}: use one of {', '.join(DEPTH_NOISE_MODELS)}"
            )
        if self.distance <= 0:
            raise ValueError(f"sensor.rgbd.distance={self.distance} must be > 0")
        if self.backdrop_distance is not None and self.backdrop_distance <= self.distance:
            raise ValueError(
                f"sensor.rgbd.backdrop_distance={self.backdrop_distance} must exceed distance "
                f"({self.distance}) to stand behind the hand, or be null (no backdrop)"
            )


@dataclass
class SimSensorConfig:
    _target_: str = "neuralfeels_sem.sensors.sim.SimSensor"
    _partial_: bool = True  # completed by the task with obj=..., class_names=...
    _convert_: str = "all"
    name: str = "sim"
    # 45 s: at 30 deg/s, alternating axes every 5 s, nine stretches turn the object 750
    # degrees about the first axis and 600 about the second; later stretches bring
    # orientations, and small parts, the first six did not: on the development objects
    # 95.3 % mean-class against 93.0 % at 30 s, lowest object 88.4 % against 74.5
    # (docs/simulation.md).
    duration_s: float = 45.0
    fps: float = 10.0
    fingers: list[str] = field(default_factory=lambda: list(FINGERS))
    camera: bool = True
    rotation_axis: list[float] = field(default_factory=lambda: [0.0, 0.0, 1.0])  # world frame
    rotation_speed_deg_s: float = 30.0
    wobble_deg: float = 4.0
    # A second axis (world frame) the object turns about in turn with rotation_axis,
    # alternate_every_s each; null: one axis, so only a band round the object is touched.
    alternate_axis: list[float] | None = field(default_factory=lambda: [0.0, 1.0, 0.0])
    alternate_every_s: float = 5.0
    # fixed: the object's centre held as high above the palm as its most upright
    # orientation needs; follow: it rests as low as its current orientation allows, so a
    # long object lying flat sits between the fingers rather than above their pads
    # (sim/trajectory.py RestHeight, docs/simulation.md).
    grasp_height: str = "fixed"
    gait_period_s: float = 1.2  # one contact-lift-move-touch cycle per finger
    contact_fraction: float = 0.75  # share of the cycle in contact
    # Press depth per finger in mm; the paper saw weaker thumb contact.
    firmness_mm: dict[str, float] = field(
        default_factory=lambda: {"index": 1.5, "middle": 1.5, "ring": 1.5, "thumb": 0.7}
    )
    seed: int = 0  # the yaml sets ${seed}
    tactile: SimTactileConfig = field(default_factory=SimTactileConfig)
    rgbd: SimRgbdConfig = field(default_factory=SimRgbdConfig)
    # scripted: the gait's sampled touches; active: touches ranked by the map's uncertainty
    # and novelty, with regrasps (sim/touch_planner.py, docs/simulation.md)
    policy: str = "scripted"
    planner: TouchPlannerConfig = field(default_factory=TouchPlannerConfig)
    # policy=active, offline: frame j is planned with the advice of frame j - this; above 1
    # the producer renders that many frames ahead of the mapper (touches on an older map).
    advice_lag_frames: int = 1
    # offline: every frame is mapped, however long it takes; realtime: frame i is due at
    # i / fps seconds of wall time and the mapper takes the newest (docs/usage.md).
    pace: str = "offline"

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"sensor.policy={self.policy!r}: use one of {', '.join(POLICIES)}")
        check_duration("sensor.duration_s", self.duration_s)
        check_rate("sensor.fps", self.fps)
        check_pace(self.pace)
        if self.advice_lag_frames < 1:
            raise ValueError(f"sensor.advice_lag_frames={self.advice_lag_frames} must be >= 1")
        if not self.fingers or any(f not in FINGERS for f in self.fingers):
            raise ValueError(
                f"sensor.fingers={self.fingers} must be a non-empty subset of {list(FINGERS)}"
            )
        if len(self.rotation_axis) != 3 or sum(v * v for v in self.rotation_axis) < 1e-12:
            raise ValueError(
                f"sensor.rotation_axis={self.rotation_axis} must be a non-zero [x, y, z]"
            )
        if self.alternate_axis is not None and (
            len(self.alternate_axis) != 3 or sum(v * v for v in self.alternate_axis) < 1e-12
        ):
            raise ValueError(
                f"sensor.alternate_axis={self.alternate_axis} must be null or a non-zero [x, y, z]"
            )
        if self.policy == "active":
            check_turn_axes(self.planner.turn, self.alternate_axis, "sensor.planner.turn")
        if self.alternate_every_s <= 0:
            raise ValueError(f"sensor.alternate_every_s={self.alternate_every_s} must be > 0")
        check_grasp_height(self.grasp_height, "sensor.grasp_height")
        if self.gait_period_s <= 0:
            raise ValueError(f"sensor.gait_period_s={self.gait_period_s} must be > 0")
        if not 0.0 < self.contact_fraction < 1.0:
            raise ValueError(f"sensor.contact_fraction={self.contact_fraction} must be in (0, 1)")
        _check_firmness("sensor.firmness_mm", self.firmness_mm)

    def rig_motion(self) -> dict:
        """The object-motion keyword arguments of SimRig that this config sets."""
        return {
            "axis": list(self.rotation_axis),
            "speed_deg_s": self.rotation_speed_deg_s,
            "wobble_deg": self.wobble_deg,
            "alternate_axis": None if self.alternate_axis is None else list(self.alternate_axis),
            "alternate_every_s": self.alternate_every_s,
            "grasp_height": self.grasp_height,
        }


@dataclass
class CollectTactileTaskConfig:
    _target_: str = "neuralfeels_sem.tasks.collect_tactile.run"
    name: str = "collect_tactile"
    root: str = "${dataset.root}"  # writes <root>/<sensor>/<material>/<id>.png
    samples_per_class_per_sensor: int = 300
    sensors: list[str] = field(default_factory=lambda: list(FINGERS))
    # Shipped objects whose regions add real-shaped touches of their materials (besides primitives).
    library_objects: list[str] = field(default_factory=lambda: list(TACTILE_DATA_OBJECTS))
    firmness_mm: dict[str, float] = field(
        default_factory=lambda: {"index": 1.5, "middle": 1.5, "ring": 1.5, "thumb": 0.7}
    )
    firmness_spread: float = 0.35  # relative std of the press depth around a finger's firmness
    max_tilt_deg: float = 10.0
    # Share of presses made with a gel edge (sensor tilted about an axis near that edge), the
    # strip-shaped imprints the rig's tilted pads make on narrow objects; 0 = all centred.
    edge_press_fraction: float = 0.0
    edge_tilt_deg: list[float] = field(default_factory=lambda: [15.0, 40.0])
    # Share of touches placed on a rim, edge or tight bend (pressed along the bisector of
    # its faces): the ridge imprints of a cup's rim; drawn independently of edge presses.
    feature_press_fraction: float = 0.0
    min_purity: float = 0.95  # share of contact pixels that must be the labelled material
    min_contact_px: int = 400
    overwrite: bool = False  # false: refuse to write into a non-empty root
    seed: int = 0  # the yaml sets ${seed}
    tactile: SimTactileConfig = field(default_factory=SimTactileConfig)
    # sensor=real (sensors/real/tactile_recording.py): the pressed object's material (one
    # of materials), new images per DIGIT, an optional time limit, and how much a contact
    # frame must differ from the last one kept (mean absolute difference in grey levels at
    # quarter size; two different real grasps differ by 8.6, a real frame with 2 grey
    # levels of added noise by 1.0: docs/hardware.md).
    material: str | None = None
    max_images: int = 200
    duration_s: float | None = None  # null: stop at max_images (or Ctrl+C)
    min_change: float = 3.0

    def __post_init__(self) -> None:
        if self.max_images < 1:
            raise ValueError(f"task.max_images={self.max_images} must be >= 1")
        check_duration("task.duration_s", self.duration_s)
        if self.min_change < 0:
            raise ValueError(f"task.min_change={self.min_change} must be >= 0 (0 keeps duplicates)")
        if self.samples_per_class_per_sensor < 1:
            raise ValueError(
                f"task.samples_per_class_per_sensor={self.samples_per_class_per_sensor} must be >= 1"
            )
        if not self.sensors or any(f not in FINGERS for f in self.sensors):
            raise ValueError(
                f"task.sensors={self.sensors} must be a non-empty subset of {list(FINGERS)}"
            )
        _check_firmness("task.firmness_mm", self.firmness_mm)
        if not 0.0 <= self.firmness_spread < 1.0:
            raise ValueError(f"task.firmness_spread={self.firmness_spread} must be in [0, 1)")
        if not 0.0 <= self.max_tilt_deg < 60.0:
            raise ValueError(f"task.max_tilt_deg={self.max_tilt_deg} must be in [0, 60)")
        if not 0.0 <= self.edge_press_fraction <= 1.0:
            raise ValueError(
                f"task.edge_press_fraction={self.edge_press_fraction} must be in [0, 1]"
            )
        if not 0.0 <= self.feature_press_fraction <= 1.0:
            raise ValueError(
                f"task.feature_press_fraction={self.feature_press_fraction} must be in [0, 1]"
            )
        if (
            len(self.edge_tilt_deg) != 2
            or not 0.0 < self.edge_tilt_deg[0] <= self.edge_tilt_deg[1] < 80.0
        ):
            raise ValueError(
                f"task.edge_tilt_deg={self.edge_tilt_deg} must be [low, high] with 0 < low <= high < 80"
            )
        if not 0.5 <= self.min_purity <= 1.0:
            raise ValueError(f"task.min_purity={self.min_purity} must be in [0.5, 1]")
        if self.min_contact_px < 1:
            raise ValueError(f"task.min_contact_px={self.min_contact_px} must be >= 1")


def register(cs) -> None:
    cs.store(group="schema/sensor", name="sim", node=SimSensorConfig)
    cs.store(group="schema/task", name="collect_tactile", node=CollectTactileTaskConfig)
