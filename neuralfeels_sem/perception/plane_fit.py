"""RANSAC fit of the dominant plane in a point cloud (a table or a wall under the object)."""

from __future__ import annotations

import numpy as np


def fit_plane_ransac(
    points: np.ndarray, inlier_m: float, iterations: int, rng: np.random.Generator
) -> tuple[np.ndarray, float] | None:
    """The plane (unit normal n, offset d with n.x + d = 0) with the most inliers, or None.

    Inliers lie within `inlier_m` of the plane. Hypotheses are drawn from three points at a
    time and scored together in one matrix product; the winner is refined by least squares
    on its inliers (the smallest singular vector of the centred inliers).
    """
    points = np.asarray(points, np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {points.shape}")
    if len(points) < 3:
        return None
    triples = points[rng.integers(0, len(points), size=(iterations, 3))]
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    norms = np.linalg.norm(normals, axis=1)
    good = norms > 1e-12  # collinear draws define no plane
    if not good.any():
        return None
    normals = normals[good] / norms[good, None]
    offsets = -(normals * triples[good, 0]).sum(axis=1)
    counts = (np.abs(points @ normals.T + offsets) < inlier_m).sum(axis=0)
    best = int(np.argmax(counts))
    inliers = points[np.abs(points @ normals[best] + offsets[best]) < inlier_m]
    centre = inliers.mean(axis=0)
    normal = np.linalg.svd(inliers - centre, full_matrices=False)[2][-1]
    return normal, float(-normal @ centre)
