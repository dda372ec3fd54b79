"""Schemas for sensor=real (devices), sensor=replay, conf/sensor/hand/ and tasks record / calibrate.

Poses in these configs are [x, y, z, rx, ry, rz]: metres and a rotation vector in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.limits import check_duration, check_rate
from neuralfeels_sem.sensors.base import check_pace
from neuralfeels_sem.sensors.real.hand_kinematics import kinematics_target
from neuralfeels_sem.sensors.replay.damage import DAMAGE_POLICIES

_STREAMS = {"QVGA": (60, 30), "VGA": (30, 15)}


def _check_pose(name: str, value: list[float] | None) -> None:
    if value is not None and len(value) not in (6, 16):
        raise ValueError(f"{name} needs 6 values [x, y, z, rx, ry, rz], got {len(value)}")


def _check_limits(name: str, limits: list[list[float]] | None) -> None:
    if limits is not None and (
        len(limits) != 16 or any(len(r) != 2 or r[0] > r[1] for r in limits)
    ):
        raise ValueError(f"{name} must be 16 [low, high] pairs with low <= high")


@dataclass
class DigitConfig:
    _target_: str = "neuralfeels_sem.sensors.real.digit.DigitArray"
    _convert_: str = "all"
    fingers: list[str] = field(default_factory=lambda: list(FINGERS))  # DIGITs in use
    # One serial per finger (printed on the sensor, e.g. D20001).
    serials: dict[str, str] = field(default_factory=lambda: {f: "" for f in FINGERS})
    resolution: str = "QVGA"  # QVGA (60 or 30 fps) or VGA (30 or 15 fps)
    fps: int = 60
    background_frames: int = (
        10  # no-contact frames captured at start; their median is the background
    )
    video_files: dict[str, str] = field(
        default_factory=dict
    )  # finger -> video of raw frames, instead of a device

    def __post_init__(self) -> None:
        if self.resolution not in _STREAMS or self.fps not in _STREAMS[self.resolution]:
            raise ValueError(
                f"sensor.digit: {self.resolution}@{self.fps} fps unsupported; use QVGA 60/30 or VGA 30/15"
            )
        if self.background_frames < 1:
            raise ValueError(
                f"sensor.digit.background_frames={self.background_frames} must be >= 1"
            )
        for finger in (*self.fingers, *self.serials, *self.video_files):
            if finger not in FINGERS:
                raise ValueError(
                    f"sensor.digit: unknown finger {finger!r}; use {', '.join(FINGERS)}"
                )


@dataclass
class RealSenseConfig:
    _target_: str = "neuralfeels_sem.sensors.real.realsense.RealSenseCamera"
    _convert_: str = "all"
    serial: str | None = None  # null: the first RealSense found
    name: str = "front_left"
    width: int = 640
    height: int = 480
    fps: int = 30
    world_T_camera: list[float] | None = None  # or calibration_file (task=calibrate output)
    calibration_file: str | None = None
    warmup_frames: int = 15
    timeout_ms: int = 1000

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0 or self.fps <= 0:
            raise ValueError(
                f"sensor.camera: {self.width}x{self.height}@{self.fps} must be positive"
            )
        _check_pose("sensor.camera.world_T_camera", self.world_T_camera)


@dataclass
class AllegroConfig:
    _target_: str = "neuralfeels_sem.sensors.real.allegro_can.AllegroCAN"
    _convert_: str = "all"
    channel: str = "can0"
    interface: str = "socketcan"  # python-can interface: socketcan, pcan, kvaser, virtual, ...
    hand_id: int = 0
    bitrate: int = 1_000_000
    timeout_s: float = 0.1  # no position reply for this long = communication loss -> emergency stop
    control: bool = False  # commands are sent only when true
    torque_limit: float = 0.3  # fraction of the firmware's full-scale torque
    kp: float = 0.6
    kd: float = 0.02
    joint_limits: list[list[float]] | None = None  # null: from the hand's kinematic model
    kinematics: str = "allegro"  # model for the DIGIT poses: allegro, leap or a class path

    def __post_init__(self) -> None:
        kinematics_target(self.kinematics)
        if not 0 <= self.hand_id <= 3:
            raise ValueError(f"sensor.hand.hand_id={self.hand_id} must be in 0..3")
        if self.timeout_s <= 0:
            raise ValueError(f"sensor.hand.timeout_s={self.timeout_s} must be > 0")
        if not 0.0 <= self.torque_limit <= 1.0:
            raise ValueError(f"sensor.hand.torque_limit={self.torque_limit} must be in [0, 1]")
        _check_limits("sensor.hand.joint_limits", self.joint_limits)


@dataclass
class DynamixelConfig:
    _target_: str = "neuralfeels_sem.sensors.real.dynamixel_hand.DynamixelHand"
    _convert_: str = "all"
    port: str = "/dev/ttyUSB0"
    baudrate: int = 4_000_000
    # The motor driving each joint, in the model's joint order (index, middle, ring, thumb;
    # 4 joints each). Stock LEAP hand: motor i drives URDF joint i.
    motor_ids: list[int] = field(default_factory=lambda: list(range(16)))
    zero_raw: int = 2048  # register value at 0 rad
    signs: list[float] | None = None
    timeout_s: float = 0.2
    control: bool = False
    current_limit_ma: float = 350.0  # torque cap, written as the motors' current limit
    joint_limits: list[list[float]] | None = None  # null: from the hand's kinematic model
    kinematics: str = "leap"  # model for the DIGIT poses: leap (LEAP Hand URDF), allegro, ...

    def __post_init__(self) -> None:
        kinematics_target(self.kinematics)
        if len(self.motor_ids) != 16 or len(set(self.motor_ids)) != 16:
            raise ValueError(
                f"sensor.hand.motor_ids needs 16 distinct ids, got {list(self.motor_ids)}"
            )
        if self.timeout_s <= 0:
            raise ValueError(f"sensor.hand.timeout_s={self.timeout_s} must be > 0")
        _check_limits("sensor.hand.joint_limits", self.joint_limits)


@dataclass
class ArucoPoseConfig:
    """Object pose from ArUco markers: detection settings here, the marker layout in object.aruco."""

    _target_: str = "neuralfeels_sem.sensors.real.aruco_pose.from_object_layout"
    _convert_: str = "all"
    layout: Any = None  # wired to ${object.aruco} by conf/sensor/real.yaml: set object.aruco
    dictionary: str = "DICT_4X4_50"
    max_reprojection_px: float = 3.0  # fits with a larger RMS are dropped (pose kept)

    def __post_init__(self) -> None:
        if not self.dictionary.startswith("DICT_"):
            raise ValueError(
                f"sensor.object_pose.dictionary={self.dictionary!r} must be an OpenCV ArUco dictionary, e.g. DICT_4X4_50"
            )
        if self.max_reprojection_px <= 0:
            raise ValueError(
                f"sensor.object_pose.max_reprojection_px={self.max_reprojection_px} must be > 0"
            )


@dataclass
class RealSensorConfig:
    _target_: str = "neuralfeels_sem.sensors.real.real_sensor.RealSensor"
    _partial_: bool = True  # completed by the task with obj=..., class_names=...
    _convert_: str = "all"
    name: str = "real"
    duration_s: float = 30.0
    fps: float = 10.0  # rate at which Frames are assembled from the device streams
    # The devices do not wait for the mapper: it takes the newest frame (docs/usage.md).
    pace: str = "realtime"
    digit: DigitConfig | None = field(default_factory=DigitConfig)
    camera: RealSenseConfig | None = field(default_factory=RealSenseConfig)
    hand: Any = None  # conf/sensor/hand/: allegro (default) or dynamixel; null: no hand
    # ArUco markers on the object (layout in object.aruco); null: the pose stays
    # sensor.world_T_object (a fixed object, or mapping.pose=track).
    object_pose: ArucoPoseConfig | None = field(default_factory=ArucoPoseConfig)
    world_T_palm: list[float] = field(default_factory=lambda: [0.0] * 6)
    world_T_object: list[float] = field(
        default_factory=lambda: [0.0] * 6
    )  # until markers or the tracker say otherwise

    def __post_init__(self) -> None:
        check_duration("sensor.duration_s", self.duration_s)
        check_rate("sensor.fps", self.fps)
        check_pace(self.pace)
        _check_pose("sensor.world_T_palm", self.world_T_palm)
        _check_pose("sensor.world_T_object", self.world_T_object)


@dataclass
class ReplaySensorConfig:
    _target_: str = "neuralfeels_sem.sensors.replay.replay_sensor.ReplaySensor"
    _partial_: bool = True
    _convert_: str = "all"
    name: str = "replay"
    recording: str | None = None  # a task=record directory, or a FeelSight log directory
    format: str = "native"  # native (task=record layout) or feelsight
    # offline: every frame, as fast as the mapper takes them; realtime: at the recorded
    # timing, the mapper taking the newest frame (docs/usage.md).
    pace: str = "offline"
    camera: str = "front-left"  # FeelSight camera to read (front-left, back-right, top-down, ...)
    max_frames: int | None = None
    # A damaged frame (bad line in frames.jsonl, missing or unreadable file): skip it with a
    # warning and count it in metrics.json, or stop the run naming the frame and file.
    on_damaged_frame: str = "skip"

    def __post_init__(self) -> None:
        check_pace(self.pace)
        if self.format not in ("native", "feelsight"):
            raise ValueError(f"sensor.format={self.format!r} must be native or feelsight")
        if self.on_damaged_frame not in DAMAGE_POLICIES:
            raise ValueError(
                f"sensor.on_damaged_frame={self.on_damaged_frame!r} must be skip or stop"
            )
        if self.max_frames is not None and self.max_frames < 1:
            raise ValueError(f"sensor.max_frames={self.max_frames} must be >= 1")


@dataclass
class RecordTaskConfig:
    _target_: str = "neuralfeels_sem.tasks.record.run"
    name: str = "record"
    duration_s: float | None = None  # null: the sensor's own duration
    max_frames: int | None = None
    out: str = "recording"  # directory inside the run directory
    feelsight: bool = False  # also export the FeelSight layout to <out>_feelsight

    def __post_init__(self) -> None:
        check_duration("task.duration_s", self.duration_s)
        if self.max_frames is not None and self.max_frames < 1:
            raise ValueError(f"task.max_frames={self.max_frames} must be >= 1")


@dataclass
class BoardConfig:
    dictionary: str = "DICT_4X4_50"
    markers_x: int = 4
    markers_y: int = 3
    marker_length_m: float = 0.03
    marker_separation_m: float = 0.006

    def __post_init__(self) -> None:
        if (
            self.markers_x < 1
            or self.markers_y < 1
            or self.marker_length_m <= 0
            or self.marker_separation_m < 0
        ):
            raise ValueError(
                "task.board: markers_x, markers_y >= 1, marker_length_m > 0, marker_separation_m >= 0"
            )


@dataclass
class CalibrateTaskConfig:
    _target_: str = "neuralfeels_sem.tasks.calibrate.run"
    name: str = "calibrate"
    images: str | None = None  # folder of images; null: capture live from sensor.camera
    intrinsics: list[float] | None = None  # [fx, fy, cx, cy] for task.images
    num_images: int = 10
    board: BoardConfig = field(default_factory=BoardConfig)
    palm_T_board: list[float] = field(default_factory=lambda: [0.0] * 6)
    world_T_palm: list[float] = field(default_factory=lambda: [0.0] * 6)
    out: str = "camera_calibration.yaml"

    def __post_init__(self) -> None:
        if self.intrinsics is not None and len(self.intrinsics) != 4:
            raise ValueError("task.intrinsics needs [fx, fy, cx, cy]")
        if self.num_images < 1:
            raise ValueError(f"task.num_images={self.num_images} must be >= 1")
        _check_pose("task.palm_T_board", self.palm_T_board)
        _check_pose("task.world_T_palm", self.world_T_palm)


def register(cs) -> None:
    cs.store(group="schema/sensor", name="real", node=RealSensorConfig)
    cs.store(group="schema/sensor", name="replay", node=ReplaySensorConfig)
    cs.store(group="schema/sensor/hand", name="allegro", node=AllegroConfig)
    cs.store(group="schema/sensor/hand", name="dynamixel", node=DynamixelConfig)
    cs.store(group="schema/task", name="record", node=RecordTaskConfig)
    cs.store(group="schema/task", name="calibrate", node=CalibrateTaskConfig)
