"""How tightly an object's surface bends where a DIGIT presses it.

A flat press shows a material's whole texture across the gel; a press on a tight bend or
a rim leaves a narrow ridge with little of it. The classifier's figures are therefore
also given per curvature bin (`eval_classifier`'s `per_curvature`), from the largest
principal curvature of the surface over the gel's footprint, recorded per image by
`task=collect_tactile` (the bins: perception/classifier/evaluate.py, curvature_bin).

The curvature comes from a quadric z = a x^2 + b x y + c y^2 (+ a plane) fitted, in the
touch's tangent frame, to dense surface samples within `radius` of the pressed point
whose normals face the same side (the far side of a thin rim is not part of the press).
Over a rim or an edge the fit spans the bend, so it reads the bend's curvature at the
footprint's scale rather than the infinite curvature of a sharp edge.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

FOOTPRINT_RADIUS_M = 0.005  # about a DIGIT contact patch's half-width
SAMPLES = 40000  # surface samples per object (about 1 mm apart on a 10 cm object)
MIN_NEIGHBOURS = 12  # fewer samples in the footprint: no curvature (NaN)


class SurfaceCurvature:
    """Largest principal curvature (1/m) of a mesh's surface around given points."""

    def __init__(
        self, mesh: trimesh.Trimesh, radius: float = FOOTPRINT_RADIUS_M, seed: int = 0
    ) -> None:
        if radius <= 0:
            raise ValueError(f"radius={radius} must be > 0")
        points, faces = trimesh.sample.sample_surface(mesh, SAMPLES, seed=seed)
        self.points = np.asarray(points, np.float64)
        self.normals = np.asarray(mesh.face_normals[faces], np.float64)
        self.radius = float(radius)
        self.tree = cKDTree(self.points)

    def at(self, point: np.ndarray, normal: np.ndarray) -> float:
        """The largest |principal curvature| (1/m) at `point` with outward `normal`; NaN
        where the footprint holds too few samples to fit."""
        n = np.asarray(normal, np.float64)
        n = n / np.linalg.norm(n)
        near = np.asarray(self.tree.query_ball_point(point, self.radius), dtype=int)
        if near.size:
            near = near[self.normals[near] @ n > 0.0]
        if near.size < MIN_NEIGHBOURS:
            return float("nan")
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        d = self.points[near] - point
        x, y, z = d @ u, d @ v, d @ n
        design = np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=1)
        (a, b, c, *_), *_ = np.linalg.lstsq(design, z, rcond=None)
        shape = np.array([[2 * a, b], [b, 2 * c]])
        return float(np.abs(np.linalg.eigvalsh(shape)).max())
