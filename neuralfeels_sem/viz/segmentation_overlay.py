"""A picture of one camera frame's object segmentation: what the mapper fused, and the truth.

The camera RGB with the segmented pixels tinted, and (in sim, where a ground-truth mask
exists) the ground truth's outline drawn over it, so a glance shows missed object parts
(inside the outline, untinted) and wrongly kept pixels (tinted outside it).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.utils.atomic import atomic_write

MASK_TINT = (40, 220, 90)  # RGB blended into segmented pixels
GT_OUTLINE = (255, 40, 40)  # RGB of the ground-truth outline
TINT_WEIGHT = 0.45


def segmentation_overlay(reading: CameraReading, mask: np.ndarray, scale: int = 2) -> np.ndarray:
    """(H*scale, W*scale, 3) uint8 RGB: `mask` tinted over the image, GT outline when known."""
    mask = np.asarray(mask, bool)
    if mask.shape != reading.depth.shape:
        raise ValueError(f"mask shape {mask.shape} does not match the image {reading.depth.shape}")
    if scale < 1:
        raise ValueError(f"scale={scale} must be >= 1")
    rgb = reading.rgb.astype(np.float32)
    rgb[mask] = (1 - TINT_WEIGHT) * rgb[mask] + TINT_WEIGHT * np.asarray(MASK_TINT, np.float32)
    size = (reading.depth.shape[1] * scale, reading.depth.shape[0] * scale)
    picture = cv2.resize(rgb.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST)
    if reading.mask is not None:
        # Outlines traced at full resolution, then scaled: thin lines on the enlarged picture.
        contours, _ = cv2.findContours(
            reading.mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
        )
        contours = [c * scale + scale // 2 for c in contours]
        cv2.drawContours(picture, contours, -1, GT_OUTLINE, 1)
    return picture


def save_segmentation_overlay(
    reading: CameraReading, mask: np.ndarray, path: Path | str, scale: int = 2
) -> Path:
    """Write `segmentation_overlay` as a PNG at `path` (atomically); returns the path."""
    path = Path(path)
    ok, encoded = cv2.imencode(".png", segmentation_overlay(reading, mask, scale)[..., ::-1])
    if not ok:
        raise ValueError(f"could not encode the overlay for {path}")
    with atomic_write(path, "wb") as f:
        f.write(encoded.tobytes())
    return path


def write_segmentation_pictures(points, out: Path) -> list[Path]:
    """A run's segmentation pictures from its PointExtractor (mapping/frame_points.py):
    `segmentation.png` (the latest segmented camera frame) and, where the simulator's
    mask scored the frames, `segmentation_worst.png` (the frame of lowest IoU). Nothing
    when the run did not segment (camera_mask=gt | none, or no camera)."""
    written = []
    if points.last_segmented is not None:
        reading, mask = points.last_segmented
        written.append(save_segmentation_overlay(reading, mask, Path(out) / "segmentation.png"))
    if points.worst_segmented is not None:
        reading, mask, _ = points.worst_segmented
        path = Path(out) / "segmentation_worst.png"
        written.append(save_segmentation_overlay(reading, mask, path))
    return written
