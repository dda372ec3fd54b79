"""Objects to press a DIGIT against when collecting a labelled tactile data set.

For every material: simple shapes of several curvatures made entirely of it (spheres,
cylinders, boxes, a capsule), plus the shipped library objects that have regions of it.
`sample_touch` draws a random surface point of a given material on one of them.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from neuralfeels_sem.errors import ConfigError
from neuralfeels_sem.objects.material_object import MaterialObject

log = logging.getLogger(__name__)


def _primitives() -> dict[str, trimesh.Trimesh]:
    return {
        "sphere_25mm": trimesh.creation.icosphere(subdivisions=4, radius=0.025),
        "sphere_45mm": trimesh.creation.icosphere(subdivisions=4, radius=0.045),
        "cylinder_20mm": trimesh.creation.cylinder(radius=0.02, height=0.08, sections=64),
        "cylinder_35mm": trimesh.creation.cylinder(radius=0.035, height=0.06, sections=64),
        "box_50x60x40mm": trimesh.creation.box(extents=(0.05, 0.06, 0.04)),
        "capsule_18mm": trimesh.creation.capsule(height=0.06, radius=0.018, count=[32, 32]),
    }


def primitive_objects(class_names: Sequence[str]) -> list[MaterialObject]:
    """Every primitive shape once per material, labelled entirely with that material."""
    out = []
    for label, material in enumerate(class_names):
        for shape, mesh in _primitives().items():
            labels = np.full(len(mesh.faces), label)
            out.append(MaterialObject(f"{material}_{shape}", mesh, labels, tuple(class_names)))
    return out


def library_objects(names: Sequence[str], class_names: Sequence[str]) -> list[MaterialObject]:
    """Shipped objects by name; an object with a material outside class_names is skipped (logged)."""
    from neuralfeels_sem.objects.library import list_objects, make_object

    known = list_objects()
    out = []
    for name in names:
        if name not in known:
            raise ConfigError(
                f"task.library_objects: unknown object {name!r}; pick from {sorted(known)}"
            )
        try:
            out.append(make_object(name, class_names))
        except ConfigError as exc:
            log.warning("skipping %s for tactile collection: %s", name, exc)
    return out


@dataclass(frozen=True)
class Touch:
    point: np.ndarray  # (3,) object frame
    normal: np.ndarray  # (3,) outward unit


def sample_touch(obj: MaterialObject, label: int, rng: np.random.Generator) -> Touch:
    """An area-uniform random point on the faces of `obj` labelled `label`, with its face normal."""
    faces = np.flatnonzero(obj.face_labels == label)
    if faces.size == 0:
        raise ValueError(f"object {obj.name!r} has no faces labelled {label}")
    areas = obj.mesh.area_faces[faces]
    face = faces[rng.choice(faces.size, p=areas / areas.sum())]
    tri = obj.mesh.vertices[obj.mesh.faces[face]]
    a, b = rng.uniform(size=2)
    if a + b > 1.0:
        a, b = 1.0 - a, 1.0 - b
    point = tri[0] + a * (tri[1] - tri[0]) + b * (tri[2] - tri[0])
    return Touch(point=point, normal=np.asarray(obj.mesh.face_normals[face], np.float64))
