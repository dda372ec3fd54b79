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
    and distance inf. Those are told apart by the faces' centroids first
    (objects/proximity.closest_surface_points `within`), so a mesh far from the samples (a run whose
    tracked pose drifted) costs no more than a near one: trimesh's own query gathers every
    face within each point's nearest-vertex distance and ran a run out of memory there.
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
    if len(mesh.faces) == 0:
        return labels, np.full(len(points), np.inf)
    from neuralfeels_sem.objects.proximity import closest_surface_points

    face, distance, closest = closest_surface_points(mesh, points, within=tolerance_m)
    near = np.flatnonzero(face >= 0)
    closest = closest[near]
    corners = np.asarray(mesh.vertices)[mesh.faces[face[near]]]  # (n, 3, 3)
    nearest_corner = np.linalg.norm(corners - closest[:, None, :], axis=2).argmin(axis=1)
    vertex = mesh.faces[face[near], nearest_corner]
    labels[near] = np.asarray(mesh.vertex_attributes["label"], dtype=np.int64)[vertex]
    return labels, distance
