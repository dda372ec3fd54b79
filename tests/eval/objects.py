"""Small material objects with exactly known ground truth, for eval and viz tests."""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject

CLASSES = tuple(DEFAULT_MATERIALS)
RADIUS = 0.05
CAP_Z = 0.8 * RADIUS  # faces above this height (both poles) are outside the regions of interest


def two_material_sphere() -> MaterialObject:
    """Sphere of 5 cm radius: plastic where y > 0, fabric where y < 0, polar caps ignored.

    The UV sphere has meridian edges in the planes x = 0 and y = 0, so every face lies
    entirely on one side of them and predictors by the sign of x or y are exact.
    """
    mesh = trimesh.creation.uv_sphere(radius=RADIUS, count=[32, 32])
    centre = mesh.triangles_center
    labels = np.where(centre[:, 1] > 0, 0, 2)
    labels[np.abs(centre[:, 2]) > CAP_Z] = IGNORE
    return MaterialObject("two_material_sphere", mesh, labels, CLASSES)


def predict_by_y(points: np.ndarray) -> np.ndarray:
    """The ground truth's rule: exact on every region-of-interest point."""
    return np.where(points[:, 1] > 0, 0, 2)


def predict_swap_x_positive(points: np.ndarray) -> np.ndarray:
    """Right on the x < 0 half, swapped on the x > 0 half: half the area is wrong."""
    right = predict_by_y(points)
    return np.where(points[:, 0] > 0, 2 - right, right)
