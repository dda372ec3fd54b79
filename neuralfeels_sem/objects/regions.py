"""Per-face material labels from region tests on face centroids, with ignored seams."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from neuralfeels_sem.objects.materials import IGNORE_NAME
from neuralfeels_sem.objects.sdf import SDF


@dataclass(frozen=True)
class Region:
    """Faces whose centroid lies inside `inside` (negative) get `material`."""

    inside: SDF
    material: str


def seam_faces(mesh: trimesh.Trimesh, names: np.ndarray, width: float) -> np.ndarray:
    """(F,) bool: faces within `width` of an edge between two different materials.

    The seam between two materials is where no touch can be classified cleanly
    (black in the paper's ground-truth maps). Edges next to "ignore" are no seam.
    """
    a, b = mesh.face_adjacency.T
    changes = (names[a] != names[b]) & (names[a] != IGNORE_NAME) & (names[b] != IGNORE_NAME)
    on_edge = np.unique(np.concatenate([a[changes], b[changes]]))
    seam = np.zeros(len(names), dtype=bool)
    if len(on_edge) == 0 or width <= 0:
        return seam
    centroids = np.asarray(mesh.triangles_center)
    distance, _ = cKDTree(centroids[on_edge]).query(centroids, distance_upper_bound=width)
    seam[np.isfinite(distance)] = True
    return seam


def small_islands(mesh: trimesh.Trimesh, names: np.ndarray, min_area: float) -> np.ndarray:
    """(F,) bool: labelled faces in edge-connected same-material patches under `min_area` m^2."""
    a, b = mesh.face_adjacency.T
    same = mesh.face_adjacency[names[a] == names[b]]
    groups = trimesh.graph.connected_components(same, nodes=np.arange(len(names)), min_len=1)
    islands = np.zeros(len(names), dtype=bool)
    for group in groups:
        if mesh.area_faces[group].sum() < min_area and names[group[0]] != IGNORE_NAME:
            islands[group] = True
    return islands


def label_faces(
    mesh: trimesh.Trimesh,
    base_material: str,
    regions: list[Region],
    seam_width: float,
    min_island_area: float = 5e-6,
) -> np.ndarray:
    """(F,) array of material names; later regions override earlier ones.

    Then seams between materials, and specks of a material smaller than
    `min_island_area` (default 5 mm^2, left where a region test grazes a fillet),
    become "ignore": no fingertip can resolve them.
    """
    centroids = np.asarray(mesh.triangles_center)
    names = np.full(len(centroids), base_material, dtype=object)
    for region in regions:
        names[region.inside(centroids) < 0] = region.material
    names = names.astype(str)
    names[seam_faces(mesh, names, seam_width)] = IGNORE_NAME
    names[small_islands(mesh, names, min_island_area)] = IGNORE_NAME
    return names
