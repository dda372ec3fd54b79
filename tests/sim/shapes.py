"""Small MaterialObjects made from trimesh primitives, for sim tests (no object library needed)."""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import MaterialObject

CLASSES = tuple(DEFAULT_MATERIALS)


def two_material_sphere(radius: float = 0.04) -> MaterialObject:
    """A sphere whose upper half (z > 0) is fabric and lower half metal."""
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    labels = np.where(
        mesh.triangles_center[:, 2] > 0, CLASSES.index("fabric"), CLASSES.index("metal")
    )
    return MaterialObject("two_material_sphere", mesh, labels, CLASSES)


def box(extents=(0.07, 0.06, 0.08)) -> MaterialObject:
    mesh = trimesh.creation.box(extents=extents)
    return MaterialObject("box", mesh, np.zeros(len(mesh.faces), int), CLASSES)
