"""Physical data per material for MuJoCo, and mapping material names to class indices."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.objects.material_object import IGNORE

IGNORE_NAME = "ignore"


@dataclass(frozen=True)
class MaterialPhysics:
    # Bulk density of a typical hand-held object of this material, hollow ones
    # included (a plastic toy or a steel shaker is a shell, a plush toy is stuffing).
    density_kg_m3: float
    # Sliding friction coefficient against a silicone fingertip (MuJoCo's first term).
    friction: float


PHYSICS: dict[str, MaterialPhysics] = {
    "plastic": MaterialPhysics(density_kg_m3=350.0, friction=0.6),
    "metal": MaterialPhysics(density_kg_m3=700.0, friction=0.4),
    "fabric": MaterialPhysics(density_kg_m3=300.0, friction=1.0),
    "wood": MaterialPhysics(density_kg_m3=600.0, friction=0.7),
}
# For class names outside the default four (the class list is config).
DEFAULT_PHYSICS = MaterialPhysics(density_kg_m3=500.0, friction=0.7)


def physics_of(material: str) -> MaterialPhysics:
    return PHYSICS.get(material, DEFAULT_PHYSICS)


def class_index(material: str, class_names: Sequence[str], what: str) -> int:
    """Index of `material` in the configured class list; ConfigError naming `what` if absent."""
    if material == IGNORE_NAME:
        return IGNORE
    if material not in class_names:
        raise ConfigError(
            f"{what} uses material {material!r}, which is not in materials={list(class_names)}: "
            f"add it to materials or pick another object"
        )
    return list(class_names).index(material)


def names_to_labels(names: Sequence[str], class_names: Sequence[str], what: str) -> np.ndarray:
    """Per-face material names ('ignore' allowed) -> int labels indexing class_names."""
    unique, inverse = np.unique(np.asarray(names, dtype=str), return_inverse=True)
    lookup = np.array([class_index(str(u), class_names, what) for u in unique], dtype=np.int64)
    return lookup[inverse.reshape(-1)]


def mass_and_friction(
    mesh_volume: float,
    areas: np.ndarray,
    labels: np.ndarray,
    class_names: Sequence[str],
    body_material: str | None = None,
) -> tuple[float, float]:
    """Mass from the volume and the body material (default: the largest by area); friction
    area-weighted over the labelled faces (MuJoCo takes one friction per geom)."""
    labelled = labels != IGNORE
    if not labelled.any():
        body = body_material or ""
        return mesh_volume * physics_of(body).density_kg_m3, physics_of(body).friction
    area_per_class = np.bincount(
        labels[labelled], weights=areas[labelled], minlength=len(class_names)
    )
    if body_material is None:
        body_material = class_names[int(area_per_class.argmax())]
    friction = (
        sum(area_per_class[i] * physics_of(name).friction for i, name in enumerate(class_names))
        / area_per_class.sum()
    )
    return mesh_volume * physics_of(body_material).density_kg_m3, float(friction)
