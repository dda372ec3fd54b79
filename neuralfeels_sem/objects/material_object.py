"""An object with per-face material ground truth: what the sim renders and eval scores against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from neuralfeels_sem.core.materials import IGNORE
from neuralfeels_sem.objects.proximity import closest_faces


@dataclass
class MaterialObject:
    """Watertight triangle mesh in metres, in the object frame (centred near the origin).

    `face_labels[i]` indexes `class_names`, or is IGNORE.
    """

    name: str
    mesh: trimesh.Trimesh
    face_labels: np.ndarray  # (F,) int
    class_names: tuple[str, ...]
    mass_kg: float = 0.1
    friction: float = 1.0

    def __post_init__(self) -> None:
        self.face_labels = np.asarray(self.face_labels, dtype=np.int64)
        if self.face_labels.shape != (len(self.mesh.faces),):
            raise ValueError(
                f"object {self.name!r}: {len(self.face_labels)} face labels for {len(self.mesh.faces)} faces"
            )
        bad = (self.face_labels != IGNORE) & (
            (self.face_labels < 0) | (self.face_labels >= len(self.class_names))
        )
        if bad.any():
            raise ValueError(
                f"object {self.name!r}: face labels outside 0..{len(self.class_names) - 1} or {IGNORE}"
            )

    @property
    def bounds_radius(self) -> float:
        """Radius of the smallest origin-centred sphere containing the mesh."""
        return float(np.linalg.norm(self.mesh.vertices, axis=1).max())

    def area_by_material(self) -> dict[str, float]:
        """Surface area (m^2) per class name, plus "ignore" for the unlabelled faces."""
        areas = np.bincount(
            self.face_labels + 1, weights=self.mesh.area_faces, minlength=len(self.class_names) + 1
        )
        return {
            "ignore": float(areas[0]),
            **{name: float(a) for name, a in zip(self.class_names, areas[1:])},
        }

    def sample_surface(
        self, count: int, seed: int = 0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Area-uniform surface samples: (points (N,3), face index (N,), label (N,))."""
        points, faces = trimesh.sample.sample_surface(self.mesh, count, seed=seed)
        return np.asarray(points), np.asarray(faces), self.face_labels[faces]

    def labels_at(self, points: np.ndarray) -> np.ndarray:
        """Ground-truth label of the closest face to each (N,3) object-frame point."""
        faces, _ = closest_faces(self.mesh, points)
        return self.face_labels[faces]
