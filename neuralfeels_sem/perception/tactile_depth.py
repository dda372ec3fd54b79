"""Local contact depth of a DIGIT: where the object presses the gel, and how far along +z.

Output for one TactileReading: a (320, 240) float32 image in metres along the sensor
camera's +z axis, 0 off-contact (the same convention as the simulator's `gt_depth`), so
`perception.pointcloud.tactile_points` turns it into object-frame contact points.

Sources:
- `gt`: the simulator's `TactileReading.gt_depth` (exact).
- `image`: a crude estimate for real sensors with no depth network. The contact mask is
  where the image differs from the sensor's no-contact background by more than
  `contact_threshold` grey levels (after a blur and a morphological opening); the depth
  inside the mask maps the intensity change linearly onto the gel's press range, from the
  gel surface (GEL_DISTANCE_M, a light touch) to GEL_DISTANCE_M - MAX_PENETRATION_M (a
  change of `full_press_intensity` or more). It ignores the illumination's direction and
  the gel's optics, so expect millimetre-level depth errors; the contact *location* is
  what it gets roughly right.
- `net`: a small U-Net trained on simulator renders over procedural and real DIGIT
  backgrounds (perception/tactile_depth_net; task=train_tactile_depth), reading the frame
  against its no-contact background; `checkpoint` null = the shipped
  assets/tactile_depth/tactile_depth.pt. A predicted contact under `min_contact_px` pixels
  counts as none. Figures: docs/perception.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import cv2
import numpy as np
import torch

from neuralfeels_sem.core.digit import GEL_DISTANCE_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.contact import shows_change
from neuralfeels_sem.perception.onnx_cpu import check_cpu_runtime
from neuralfeels_sem.perception.tactile_depth_net import DepthNetPredictor

TactileDepthSource = Literal["gt", "image", "net"]
SOURCES = get_args(TactileDepthSource)


@dataclass
class TactileDepthConfig:
    """`mapping.mapper.tactile_depth`: where a touch's contact depth comes from."""

    # net: the learned network (sim-trained; what a real rig has) | gt: simulator depth
    # (an oracle) | image: background-difference estimate. A TactileDepthSource; typed
    # `str` because OmegaConf 2.3 rejects Literal annotations.
    source: str = "net"
    checkpoint: str | None = None  # source=net: a tactile_depth.pt; null = the shipped one
    contact_threshold: float = 12.0  # grey levels of change that count as contact
    full_press_intensity: float = 60.0  # grey levels of change at the deepest press
    blur_px: int = 7
    min_contact_px: int = 150
    # source=net on the CPU: onnxruntime (perception/onnx_cpu.py: about half the time a
    # frame, depth within float rounding) | torch (eager, to the bit of older runs).
    cpu_runtime: str = "onnxruntime"

    def __post_init__(self) -> None:
        key = "mapping.mapper.tactile_depth"
        check_cpu_runtime(f"{key}.cpu_runtime", self.cpu_runtime)
        if self.source not in SOURCES:
            raise ValueError(f"{key}.source={self.source!r} is unknown; use one of {SOURCES}")
        if not 0 < self.contact_threshold < self.full_press_intensity:
            raise ValueError(
                f"{key} needs 0 < contact_threshold ({self.contact_threshold}) "
                f"< full_press_intensity ({self.full_press_intensity})"
            )
        if self.blur_px < 1 or self.blur_px % 2 == 0:
            raise ValueError(f"{key}.blur_px={self.blur_px} must be odd and >= 1")
        if self.min_contact_px < 0:
            raise ValueError(f"{key}.min_contact_px={self.min_contact_px} must be >= 0")


class TactileDepth:
    """Contact depth from a tactile reading (`config.source` = gt | image | net)."""

    def __init__(
        self, config: TactileDepthConfig | None = None, device: str | torch.device = "cpu"
    ) -> None:
        config = config or TactileDepthConfig()  # ranges: TactileDepthConfig.__post_init__
        self.source = config.source
        self.contact_threshold = float(config.contact_threshold)
        self.full_press_intensity = float(config.full_press_intensity)
        self.blur_px = int(config.blur_px)
        self.min_contact_px = int(config.min_contact_px)
        # Constructing the predictor reads nothing; the checkpoint loads in `load` or on the
        # first touch.
        self.net = DepthNetPredictor(
            config.checkpoint, self.min_contact_px, device, cpu_runtime=config.cpu_runtime
        )
        self.unchanged = 0  # readings that showed no change and skipped the network

    def load(self) -> None:
        """Load the network now (source=net; else nothing to load), not on the first touch."""
        if self.source == "net":
            self.net.load()

    def __call__(self, reading: TactileReading) -> np.ndarray:
        if self.source == "gt":
            if reading.gt_depth is None:
                raise DataError(
                    f"tactile depth source=gt but {reading.finger} has no simulator depth; "
                    "use mapping.mapper.tactile_depth.source=image on real sensors"
                )
            return np.asarray(reading.gt_depth, dtype=np.float32)
        if self.source == "net":
            return self.batch([reading])[0]
        return self.from_image(reading.image, reading.background, reading.finger)

    def batch(self, readings: list[TactileReading]) -> list[np.ndarray]:
        """`self(r)` for each reading; the network takes them in one batch (a frame's
        fingers: one forward pass instead of four). A frame that shows no change from its
        background (contact.shows_change) has no contact and skips the network: on the
        simulated rig a quarter to a half of the fingers' frames."""
        if self.source != "net":
            return [self(r) for r in readings]
        backgrounds = [self._background(r.background, r.finger) for r in readings]
        depths = [np.zeros(r.image.shape[:2], np.float32) for r in readings]
        pairs = enumerate(zip(readings, backgrounds))
        changed = [i for i, (r, bg) in pairs if shows_change(r.image, bg)]
        self.unchanged += len(readings) - len(changed)
        if changed:
            images = np.stack([readings[i].image for i in changed])
            predicted = self.net.predict(images, np.stack([backgrounds[i] for i in changed]))
            for i, depth in zip(changed, predicted):
                depths[i] = depth
        return depths

    def _background(self, background: np.ndarray | None, finger: str) -> np.ndarray:
        if background is None:
            raise DataError(
                f"tactile depth source={self.source} needs a no-contact background for {finger}; "
                "record one before touching (the sensor backend stores it in TactileReading.background)"
            )
        return background

    def intensity_change(self, image: np.ndarray, background: np.ndarray) -> np.ndarray:
        """Blurred mean absolute difference to the background, in grey levels (H, W)."""
        if image.shape != background.shape:
            raise ValueError(
                f"image {image.shape} and background {background.shape} differ in shape"
            )
        diff = np.abs(image.astype(np.float32) - background.astype(np.float32)).mean(axis=2)
        return cv2.GaussianBlur(diff, (self.blur_px, self.blur_px), 0)

    def contact_mask(self, change: np.ndarray) -> np.ndarray:
        """Pixels that changed by more than the threshold, without specks; all False if too small."""
        mask = (change > self.contact_threshold).astype(np.uint8)
        kernel = np.ones((5, 5), np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel).astype(bool)
        if mask.sum() < self.min_contact_px:
            mask[:] = False
        return mask

    def from_image(
        self, image: np.ndarray, background: np.ndarray | None, finger: str = "sensor"
    ) -> np.ndarray:
        change = self.intensity_change(image, self._background(background, finger))
        mask = self.contact_mask(change)
        press = np.clip(change / self.full_press_intensity, 0.0, 1.0)
        depth = GEL_DISTANCE_M - MAX_PENETRATION_M * press
        return np.where(mask, depth, 0.0).astype(np.float32)
