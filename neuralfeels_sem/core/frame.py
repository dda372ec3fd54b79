"""The one data type every sensor backend (sim, real, replay) yields.

Conventions (see neuralfeels_sem/core/geometry.py): poses are 4x4 `world_T_x`,
cameras are OpenCV (+z forward), depth in metres with 0 = invalid. Tactile images
are DIGIT-sized: 320 rows x 240 columns x RGB uint8. Ground-truth fields are None
on real hardware.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from neuralfeels_sem.core.geometry import Intrinsics, check_pose
from neuralfeels_sem.core.hand import FINGERS


@dataclass
class TactileReading:
    """One DIGIT image plus its pose and (in sim) per-pixel ground truth."""

    finger: str
    image: np.ndarray  # (320, 240, 3) uint8
    # Pose of the DIGIT's internal camera (OpenCV, +z looks through the gel toward the object).
    world_T_sensor: np.ndarray
    intrinsics: Intrinsics  # of the DIGIT's internal camera
    background: np.ndarray | None = (
        None  # the no-contact frame of this sensor, for the contact gate
    )
    # Sim ground truth (None on hardware):
    gt_contact_mask: np.ndarray | None = None  # (320, 240) bool
    gt_depth: np.ndarray | None = (
        None  # (320, 240) float32, metres along +z of the sensor camera, 0 off-contact
    )
    gt_material: np.ndarray | None = None  # (320, 240) int16 class index, -1 = no contact / ignore

    def __post_init__(self) -> None:
        if self.image.ndim != 3 or self.image.shape[2] != 3 or self.image.dtype != np.uint8:
            raise ValueError(
                f"tactile image of {self.finger} must be (H, W, 3) uint8, got {self.image.shape} {self.image.dtype}"
            )
        check_pose(self.world_T_sensor, f"world_T_sensor of {self.finger}")

    @property
    def in_contact_gt(self) -> bool | None:
        return None if self.gt_contact_mask is None else bool(self.gt_contact_mask.any())


@dataclass
class CameraReading:
    """One RGB-D frame from the external camera."""

    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 metres, 0 = invalid
    intrinsics: Intrinsics
    world_T_camera: np.ndarray
    mask: np.ndarray | None = None  # (H, W) bool object mask (sim GT or a segmenter)
    name: str = "front_left"

    def __post_init__(self) -> None:
        h, w = self.depth.shape[:2]
        if self.rgb.shape[:2] != (h, w):
            raise ValueError(
                f"camera rgb {self.rgb.shape} and depth {self.depth.shape} differ in size"
            )
        if (h, w) != (self.intrinsics.height, self.intrinsics.width):
            raise ValueError(f"camera image {w}x{h} does not match its intrinsics")
        check_pose(self.world_T_camera, "world_T_camera")


@dataclass
class Frame:
    """Everything observed at one time step."""

    index: int
    time_s: float
    # Object pose used for mapping: ground truth in sim, markers or tracker on hardware.
    world_T_object: np.ndarray
    tactile: dict[str, TactileReading] = field(default_factory=dict)
    camera: CameraReading | None = None
    gt_world_T_object: np.ndarray | None = None  # sim ground truth, kept even when tracking
    joint_positions: np.ndarray | None = None  # (16,) hand joints in radians, when known
    # sensor.pace=realtime: a frame overtaken by a newer one before the mapper could take
    # it, made for its touches alone (no camera reading; pipeline/producer.py).
    touches_only: bool = False

    def __post_init__(self) -> None:
        check_pose(self.world_T_object, "world_T_object")
        for name in self.tactile:
            if name not in FINGERS:
                raise ValueError(f"unknown finger {name!r}; expected one of {FINGERS}")
