"""Shape-aware matching: ground-truth samples take their label from the reconstructed mesh.

Querying the field at ground-truth surface points (`matching_pct`) never charges a run
for a surface that is missing or misplaced. Here each sample takes the predicted label
of the nearest point of the extracted material mesh; a sample whose nearest mesh point
is farther than a tolerance gets NO_PREDICTION, which is wrong for every class.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from neuralfeels_sem.eval.matching import NO_PREDICTION

if TYPE_CHECKING:  # the config schema imports check_tolerance: keep trimesh out of start-up
    import trimesh


def check_tolerance(tolerance_m: float) -> None:
    if not np.isfinite(tolerance_m) or tolerance_m <= 0:
        raise ValueError(
            f"eval.mesh_match_tolerance_m={tolerance_m} must be a distance > 0 in metres (e.g. 0.005)"
        )


def labels_from_mesh(
    mesh: trimesh.Trimesh, points: np.ndarray, tolerance_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """(label per point, distance to the mesh in metres) for (N, 3) points in the mesh's frame.

    The label at the nearest surface point is that of the nearest vertex of the triangle it
    lies on (the mesh carries one predicted class per vertex in
    `mesh.vertex_attributes["label"]`); points farther than `tolerance_m` get NO_PREDICTION
    and distance inf. Those are told apart first by the faces' centroids, so a mesh far
    from the samples (a run whose tracked pose drifted) costs no more than a near one:
    trimesh's own query gathers every face within each point's nearest-vertex distance and
    ran a run out of memory there.
    """
    check_tolerance(tolerance_m)
    if "label" not in mesh.vertex_attributes:
        raise ValueError(
            "the mesh has no per-vertex 'label' attribute (use mapping.mesh.extract_mesh)"
        )
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {points.shape}")
    labels = np.full(len(points), NO_PREDICTION, np.int64)
    distance = np.full(len(points), np.inf)
    if len(mesh.faces) == 0:
        return labels, distance
    near = np.flatnonzero(_may_be_within(mesh, points, tolerance_m))
    if len(near):
        labels[near], distance[near] = _nearest_labels(mesh, points[near])
    labels[distance > tolerance_m] = NO_PREDICTION
    distance[distance > tolerance_m] = np.inf
    return labels, distance


def _may_be_within(mesh: trimesh.Trimesh, points: np.ndarray, tolerance_m: float) -> np.ndarray:
    """(N,) bool: could a face lie within `tolerance_m` of the point? A face that does has
    its centroid within tolerance + its centroid-to-corner radius."""
    from scipy.spatial import cKDTree

    triangles = np.asarray(mesh.triangles)
    centroids = triangles.mean(axis=1)
    radius = float(np.linalg.norm(triangles - centroids[:, None], axis=2).max())
    reach, _ = cKDTree(centroids).query(points, k=1, distance_upper_bound=tolerance_m + radius)
    return np.isfinite(reach)


def _nearest_labels(mesh: trimesh.Trimesh, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(label, distance) per point from its closest face (exact, objects/proximity.py)."""
    import trimesh

    from neuralfeels_sem.objects.proximity import closest_faces

    face, distance = closest_faces(mesh, points)
    closest = trimesh.triangles.closest_point(np.asarray(mesh.triangles)[face], points)
    corners = np.asarray(mesh.vertices)[mesh.faces[face]]  # (N, 3, 3)
    nearest_corner = np.linalg.norm(corners - closest[:, None, :], axis=2).argmin(axis=1)
    vertex = mesh.faces[face, nearest_corner]
    return np.asarray(mesh.vertex_attributes["label"], dtype=np.int64)[vertex], distance
