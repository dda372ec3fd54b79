"""The painted sphere (mapping/painted_sphere.py) as a pose source's MapView, and helpers."""

from __future__ import annotations

import numpy as np
import torch

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.mapping.painted_sphere import (  # noqa: F401  (re-exported for tests)
    RADIUS,
    frame_of,
    render,
    sphere_sdf,
    turning,
)
from neuralfeels_sem.perception.pointcloud import camera_points


class SphereMapper:
    """The MapView of a pose source: the camera's object pixels, the exact sphere SDF."""

    has_surface = True

    def frame_points(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        return {"camera": camera_points(frame.camera, world_T_object)}

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return sphere_sdf(x)


def surface_samples(n: int = 500) -> np.ndarray:
    d = np.random.default_rng(0).normal(size=(n, 3))
    return RADIUS * d / np.linalg.norm(d, axis=1, keepdims=True)


def turned_deg(a: np.ndarray, b: np.ndarray) -> float:
    rot = a[:3, :3].T @ b[:3, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0))))
