"""Objects to press a DIGIT against when collecting a labelled tactile data set.

For every material: simple shapes of several curvatures made entirely of it (spheres,
cylinders, boxes, a capsule), plus the shipped library objects that have regions of it.
`sample_touch` draws a random surface point of a given material on one of them;
`sample_feature_touch` draws one on a rim, edge or tight bend (see `FeatureEdges`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from neuralfeels_sem.core.errors import ConfigError
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


# An edge between two faces is a feature (rim, corner, bead) where the surface turns by
# more than this angle, or bends tighter than this radius (mesh-resolution independent).
FEATURE_MIN_ANGLE_DEG = 35.0
FEATURE_MAX_RADIUS_M = 0.008


@dataclass(frozen=True)
class FeatureEdges:
    """The mesh edges where the surface turns sharply: where a fingertip presses a rim.

    Area-uniform touches almost never land on a 4 mm rim or a box edge, yet the rig's
    fingers press them often (a candle holder's cup rim, a shaker's lid lip), and such an
    imprint is a ridge with little texture. Per edge: its two end points, the bisector of
    its two faces' normals, its length and the material label shared by both faces (-1
    where they differ, never sampled).
    """

    start: np.ndarray  # (E, 3)
    end: np.ndarray  # (E, 3)
    normal: np.ndarray  # (E, 3) unit bisector of the two face normals
    length: np.ndarray  # (E,)
    label: np.ndarray  # (E,)

    @classmethod
    def of(
        cls,
        obj: MaterialObject,
        min_angle_deg: float = FEATURE_MIN_ANGLE_DEG,
        max_radius_m: float = FEATURE_MAX_RADIUS_M,
    ) -> FeatureEdges:
        mesh = obj.mesh
        pairs = mesh.face_adjacency  # (E, 2) faces sharing an edge
        angles = mesh.face_adjacency_angles  # (E,) radians between the face normals
        centres = mesh.triangles_center
        # Curvature ~ turning angle over the distance between the two faces' centres.
        gap = np.linalg.norm(centres[pairs[:, 0]] - centres[pairs[:, 1]], axis=1)
        bend_radius = gap / np.maximum(angles, 1e-9)
        sharp = (angles >= np.deg2rad(min_angle_deg)) | (bend_radius <= max_radius_m)
        labels = obj.face_labels[pairs]
        label = np.where(labels[:, 0] == labels[:, 1], labels[:, 0], -1)
        edges = mesh.face_adjacency_edges
        normal = mesh.face_normals[pairs[:, 0]] + mesh.face_normals[pairs[:, 1]]
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        start, end = mesh.vertices[edges[:, 0]], mesh.vertices[edges[:, 1]]
        keep = sharp & (label >= 0)
        return cls(
            start=start[keep],
            end=end[keep],
            normal=normal[keep],
            length=np.linalg.norm(end - start, axis=1)[keep],
            label=label[keep],
        )

    def has(self, label: int) -> bool:
        return bool((self.label == label).any())


def sample_feature_touch(edges: FeatureEdges, label: int, rng: np.random.Generator) -> Touch | None:
    """A length-uniform random point on the feature edges labelled `label`, pressed along
    the bisector of the edge's faces; None when the object has no such edge."""
    candidates = np.flatnonzero(edges.label == label)
    if candidates.size == 0:
        return None
    weights = edges.length[candidates]
    edge = candidates[rng.choice(candidates.size, p=weights / weights.sum())]
    t = rng.uniform()
    point = edges.start[edge] + t * (edges.end[edge] - edges.start[edge])
    return Touch(point=point, normal=np.asarray(edges.normal[edge], np.float64))


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
