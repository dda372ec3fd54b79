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
"""

from __future__ import annotations

import cv2
import numpy as np

from neuralfeels_sem.errors import ConfigError, DataError
from neuralfeels_sem.sensors.frame import TactileReading
from neuralfeels_sem.sim.digit_geometry import GEL_DISTANCE_M, MAX_PENETRATION_M

SOURCES = ("gt", "image")


class TactileDepth:
    """Contact depth from a tactile reading (`source` = gt | image)."""

    def __init__(
        self,
        source: str = "gt",
        contact_threshold: float = 12.0,
        full_press_intensity: float = 60.0,
        blur_px: int = 7,
        min_contact_px: int = 150,
    ) -> None:
        if source not in SOURCES:
            raise ConfigError(f"tactile depth source={source!r} is unknown; use one of {SOURCES}")
        if contact_threshold <= 0 or full_press_intensity <= contact_threshold:
            raise ValueError(
                f"need 0 < contact_threshold ({contact_threshold}) < full_press_intensity ({full_press_intensity})"
            )
        if blur_px < 1 or blur_px % 2 == 0:
            raise ValueError(f"blur_px={blur_px} must be an odd number >= 1")
        if min_contact_px < 0:
            raise ValueError(f"min_contact_px={min_contact_px} must be >= 0")
        self.source = source
        self.contact_threshold = float(contact_threshold)
        self.full_press_intensity = float(full_press_intensity)
        self.blur_px = int(blur_px)
        self.min_contact_px = int(min_contact_px)

    def __call__(self, reading: TactileReading) -> np.ndarray:
        if self.source == "gt":
            if reading.gt_depth is None:
                raise DataError(
                    f"tactile depth source=gt but {reading.finger} has no simulator depth; "
                    "use mapping.mapper.tactile_depth.source=image on real sensors"
                )
            return np.asarray(reading.gt_depth, dtype=np.float32)
        return self.from_image(reading.image, reading.background, reading.finger)

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
        if background is None:
            raise DataError(
                f"tactile depth source=image needs a no-contact background for {finger}; "
                "record one before touching (the sensor backend stores it in TactileReading.background)"
            )
        change = self.intensity_change(image, background)
        mask = self.contact_mask(change)
        press = np.clip(change / self.full_press_intensity, 0.0, 1.0)
        depth = GEL_DISTANCE_M - MAX_PENETRATION_M * press
        return np.where(mask, depth, 0.0).astype(np.float32)
