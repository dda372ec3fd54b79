"""The surface points of one frame, in the object frame: the camera's and each touch's."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.perception.pointcloud import camera_points, tactile_points
from neuralfeels_sem.perception.tactile_depth import TactileDepth


class PointExtractor:
    """Back-projects a frame's camera depth (inside its mask when `use_camera_mask`) and
    each finger's contact depth (from `tactile_depth`) into object-frame points."""

    def __init__(self, use_camera_mask: bool, tactile_depth: TactileDepth) -> None:
        self.use_camera_mask = bool(use_camera_mask)
        self.tactile_depth = tactile_depth

    def __call__(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        """Object-frame surface points per source: `camera` and each finger in contact."""
        return self.extract(frame, world_T_object, every_pixel=False)[0]

    def extract(
        self, frame: Frame, world_T_object: np.ndarray, every_pixel: bool
    ) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
        """The points per source and, with `every_pixel`, the points of all valid camera pixels.

        The space prior carves along every pixel's ray, mask or not: for it the camera is
        back-projected once, without its mask, and the surface points are the pixels inside
        the mask (the same points, in the same order, as camera_points(..., use_mask=True)).
        """
        out: dict[str, np.ndarray] = {}
        every = None
        reading = frame.camera
        if reading is not None and every_pixel:
            every = camera_points(reading, world_T_object, use_mask=False)
            out["camera"] = every
            if self.use_camera_mask and reading.mask is not None:
                if reading.mask.shape != reading.depth.shape:
                    raise ValueError(
                        f"mask shape {reading.mask.shape} does not match depth shape "
                        f"{reading.depth.shape}"
                    )
                # backproject keeps the finite, positive depths in row-major pixel order.
                valid = np.isfinite(reading.depth) & (reading.depth > 0)
                out["camera"] = every[reading.mask.astype(bool)[valid]]
        elif reading is not None:
            out["camera"] = camera_points(reading, world_T_object, self.use_camera_mask)
        for finger, reading in frame.tactile.items():
            pts = tactile_points(reading, self.tactile_depth(reading), world_T_object)
            if len(pts):
                out[finger] = pts
        return out, every
