"""Material-label helpers of the sim's pyrender SEG passes (tactile and camera renderers).

The offscreen renderer and camera conversions they share with other layers live in
`utils/offscreen.py`.
"""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject


def split_by_material(obj: MaterialObject) -> list[tuple[int, trimesh.Trimesh]]:
    """One submesh per face label present (IGNORE included), sorted by label.

    Vertices are shared between submeshes so material borders stay watertight.
    """
    out = []
    for label in np.unique(obj.face_labels):
        faces = np.nonzero(obj.face_labels == label)[0]
        sub = obj.mesh.submesh([faces], append=True, repair=False)
        out.append((int(label), sub))
    return out


def seg_code(label: int) -> int:
    """Colour code of a material label in a SEG pass: 0 = nothing, 1 = IGNORE, 2+ = classes."""
    return 1 if label == IGNORE else label + 2


def decode_seg(seg_rgb: np.ndarray) -> np.ndarray:
    """SEG-pass colour (H, W, 3) -> label map int16 (-1 for nothing and IGNORE faces).

    Codes are written into the red and green channels (code = r + 256 * g) so more than
    254 classes never alias.
    """
    code = seg_rgb[..., 0].astype(np.int32) + 256 * seg_rgb[..., 1].astype(np.int32)
    labels = code - 2
    labels[code < 2] = IGNORE
    return labels.astype(np.int16)


def seg_colour(label: int) -> np.ndarray:
    code = seg_code(label)
    return np.array([code % 256, code // 256, 0], dtype=np.uint8)
