"""Exact closest-face queries, fast for points near the surface.

trimesh.proximity.closest_point preselects faces by bounding boxes and can return a
face that is not the closest (a few percent of points, off by up to ~30 um on our
meshes). Here the k faces with the nearest centroids are candidates. A face's points
lie within its radius r_f (centroid to farthest vertex) of its centroid c_f, so
|p - c_f| - r_f bounds its distance from below: the nearest-centroid face is measured
first, and only candidates whose bound is below that distance are measured after it
(two or three per point near the surface). A point is done when no face beyond the
candidates can be closer (the (k+1)-th centroid minus the largest radius is no
nearer), otherwise k grows until it is, up to every face.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

_MAX_PAIRS = 1 << 20  # (point, triangle) pairs per batch: bounds memory to ~100 MB


def _measure(triangles: np.ndarray, faces: np.ndarray, points: np.ndarray):
    """Closest points on faces[i] to points[i] and their distances, in batches."""
    closest = np.empty((len(points), 3))
    for s in range(0, len(points), _MAX_PAIRS):
        closest[s : s + _MAX_PAIRS] = trimesh.triangles.closest_point(
            triangles[faces[s : s + _MAX_PAIRS]], points[s : s + _MAX_PAIRS]
        )
    return closest, np.linalg.norm(closest - points, axis=1)


def _closest_among(
    triangles: np.ndarray,
    radii: np.ndarray,
    points: np.ndarray,
    candidates: np.ndarray,
    centroid_distance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best of the (N, k) candidate faces per point (nearest centroid first, at
    `centroid_distance`): (face (N,), distance (N,), the closest point on it (N, 3))."""
    faces = candidates[:, 0].copy()
    closest, distance = _measure(triangles, faces, points)
    could = centroid_distance - radii[candidates] < distance[:, None]
    could[:, 0] = False
    rows, cols = np.nonzero(could)
    if len(rows):
        other, other_distance = _measure(triangles, candidates[rows, cols], points[rows])
        order = np.lexsort((other_distance, rows))  # each row's nearest first
        first = order[np.unique(rows[order], return_index=True)[1]]
        better = first[other_distance[first] < distance[rows[first]]]
        point = rows[better]
        faces[point] = candidates[point, cols[better]]
        distance[point], closest[point] = other_distance[better], other[better]
    return faces, distance, closest


def closest_faces(
    mesh: trimesh.Trimesh, points: np.ndarray, k: int = 16, within: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(face index (N,), distance (N,)) of the closest face to each (N, 3) point.

    `within`: only faces that close count; a point with none gets face -1 and distance inf,
    found from the centroids alone, so points far from the mesh cost no face tests."""
    faces, distance, _ = closest_surface_points(mesh, points, k, within)
    return faces, distance


def closest_surface_points(
    mesh: trimesh.Trimesh, points: np.ndarray, k: int = 16, within: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """closest_faces with the closest point on each face too: (face (N,), distance (N,),
    point (N, 3); NaN where no face lies `within`). `k`: candidate faces per point in the
    first round (100k points within 0.1 mm of the plushie's 20k faces, 2-core CPU: 1.3 s at
    16, 2.6 s at 8, 1.7 s at 32); points it cannot settle get 4k, and so on."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"closest-face search: points must be (N, 3), got {points.shape}")
    triangles = np.asarray(mesh.triangles)
    centroids = triangles.mean(axis=1)
    radii = np.linalg.norm(triangles - centroids[:, None], axis=2).max(axis=1)
    radius = float(radii.max())
    tree = cKDTree(centroids)
    faces = np.full(len(points), -1, dtype=np.int64)
    distance = np.full(len(points), np.inf)
    closest = np.full((len(points), 3), np.nan)
    todo = np.arange(len(points))
    if within is not None:  # a face within it has its centroid within it + radius
        reach, _ = tree.query(points, k=1, distance_upper_bound=within + radius)
        todo = todo[np.isfinite(reach)]
    while len(todo):
        k = min(k, len(centroids))
        everything = k == len(centroids)
        # one centroid more than the candidates: how near a face left out could be
        near, index = tree.query(points[todo], k=k if everything else k + 1)
        near, index = near.reshape(len(todo), -1), index.reshape(len(todo), -1)
        found = _closest_among(triangles, radii, points[todo], index[:, :k], near[:, :k])
        faces[todo], distance[todo], closest[todo] = found
        if everything:
            break
        todo = todo[near[:, k] - radius < distance[todo]]
        k *= 4
    if within is not None:
        beyond = distance > within
        faces[beyond], distance[beyond], closest[beyond] = -1, np.inf, np.nan
    return faces, distance, closest
