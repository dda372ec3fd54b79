"""What the gel feels on a face that scoring ignores: the nearest labelled face's material.

Ignored faces (the seams between materials, the face an object rests on, a custom mesh's
`ignore` faces) are left out of scoring; they are not made of nothing. A real seam is one
material or the other and a real base is made of something, so a texture of no material
there shows the classifier an imprint no real object leaves, and it reads one anyway (on
generated objects a few per cent of the trained contact points lie on such faces). The
tactile renderer therefore presses each ignored face as the material of the nearest
labelled face; the frame's ground truth keeps it ignored.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.sim.gel_optics import object_points

IGNORED_FACES = ("nearest", "generic")


def check_ignored_faces(mode: str) -> None:
    if mode not in IGNORED_FACES:
        raise ValueError(
            f"sensor.tactile.ignored_faces={mode!r} must be one of {', '.join(IGNORED_FACES)}"
        )


class FeltMaterial:
    """Per-pixel material the gel feels: the face's own, or for an ignored face the
    material of the labelled face whose centroid lies nearest (`nearest`; all faces
    ignored: none) or none (`generic`: the renderer's texture of no material)."""

    def __init__(self, obj: MaterialObject, mode: str) -> None:
        check_ignored_faces(mode)
        labels = np.asarray(obj.face_labels)
        labelled = labels != IGNORE
        self._tree = None
        if mode == "nearest" and labelled.any() and not labelled.all():
            self._tree = cKDTree(np.asarray(obj.mesh.triangles_center)[labelled])
            self._labels = labels[labelled].astype(np.int16)

    def __call__(
        self, labels: np.ndarray, depth: np.ndarray, hit: np.ndarray, object_T_sensor: np.ndarray
    ) -> np.ndarray:
        """(H, W) labels with every ignored pixel the object covers (`hit`, at `depth` along
        the sensor's +z) given its felt material; `labels` itself when there is none."""
        if self._tree is None:
            return labels
        v, u = np.nonzero(hit & (labels == IGNORE))
        if len(v) == 0:
            return labels
        points = object_points(v, u, depth[v, u], 0, 0, object_T_sensor)
        felt = labels.copy()
        felt[v, u] = self._labels[self._tree.query(points)[1]]
        return felt
