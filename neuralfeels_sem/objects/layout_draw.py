"""Drawn material layouts, painted and checked: generated objects' and custom meshes'.

A layout (random_layouts.draw_layout) is painted onto a mesh with the shipped objects'
regions of interest: seams between materials and the face it rests on are ignored. A
painted layout that fails `layout_problems` is never used: it is drawn again from the
next sub-seed. `object=random` draws its shape and layout together (random_object.py);
`object=custom object.layout_seed=K` draws only the layout, onto the user's mesh.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Sequence

import numpy as np
import trimesh

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.objects import sdf as S
from neuralfeels_sem.objects.materials import IGNORE_NAME
from neuralfeels_sem.objects.procedural import BOTTOM_BAND, SEAM
from neuralfeels_sem.objects.random_layouts import Layout, draw_layout
from neuralfeels_sem.objects.regions import Region, label_faces, small_islands

log = logging.getLogger(__name__)

# Every connected patch of a material covers at least this (m^2): about half a DIGIT
# gel (1.8 x 2.4 cm), the size of patchwork's badge. Smaller ones cannot be scored fairly.
MIN_PATCH_AREA_M2 = 2e-4
MIN_LABELLED_SHARE = 0.6  # of the surface area inside the regions of interest
MAX_SUB_SEEDS = 50


def paint(mesh: trimesh.Trimesh, layout: Layout) -> np.ndarray:
    """(F,) material names of `layout` on `mesh`, its resting face (lowest z) ignored."""
    resting_face = Region(S.half_space_below(mesh.bounds[0, 2] + BOTTOM_BAND), IGNORE_NAME)
    return label_faces(mesh, layout.base_material, [*layout.regions, resting_face], SEAM)


def layout_problems(
    mesh: trimesh.Trimesh, names: np.ndarray, materials: Sequence[str]
) -> list[str]:
    """Why a painted layout cannot be scored fairly (empty: it can)."""
    found = []
    unique, inverse = np.unique(names, return_inverse=True)
    present = dict(zip(unique, np.bincount(inverse.reshape(-1), weights=mesh.area_faces)))
    missing = [m for m in materials if present.get(m, 0.0) < MIN_PATCH_AREA_M2]
    if missing:
        found.append(f"material {missing} missing or below {1e4 * MIN_PATCH_AREA_M2:.0f} cm^2")
    if small_islands(mesh, names, MIN_PATCH_AREA_M2).any():
        found.append(f"a patch below the minimum {1e4 * MIN_PATCH_AREA_M2:.0f} cm^2")
    labelled = 1.0 - present.get(IGNORE_NAME, 0.0) / float(mesh.area)
    if labelled < MIN_LABELLED_SHARE:
        found.append(f"only {100 * labelled:.0f} % of the surface labelled")
    return found


def shape_key(mesh: trimesh.Trimesh) -> int:
    """A number that tells meshes apart (face count, extents to 0.1 mm): mixed into the
    layout's random stream so that one layout seed draws different layouts on different
    meshes, and the same layout on the same mesh wherever it is loaded."""
    extents = np.round(np.asarray(mesh.extents) * 1e4).astype(np.int64)
    return zlib.crc32(np.array([len(mesh.faces), *extents], dtype=np.int64).tobytes())


def draw_on_mesh(
    mesh: trimesh.Trimesh, seed: int, pool: Sequence[str], what: str
) -> tuple[np.ndarray, dict]:
    """The first layout from sub-seed 0 on that passes `layout_problems` on this mesh:
    (per-face material names, record of seed, sub-seed, materials and region kinds).

    DataError naming `what` when none of MAX_SUB_SEEDS draws passes (a mesh too small
    for a patch of the minimum area, say).
    """
    last: list[str] = []
    shape = shape_key(mesh)
    for sub_seed in range(MAX_SUB_SEEDS):
        layout = draw_layout(mesh, pool, np.random.default_rng([seed, sub_seed, shape]))
        names = paint(mesh, layout)
        last = layout_problems(mesh, names, layout.materials)
        if not last:
            record = {"layout_seed": seed, "sub_seed": sub_seed}
            return names, {**record, "materials": layout.materials, "regions": layout.kinds}
        log.info("%s layout %d sub-seed %d redrawn: %s", what, seed, sub_seed, "; ".join(last))
    raise DataError(
        f"{what}: no material layout from seed {seed} passed its checks in {MAX_SUB_SEEDS} "
        f"draws (last: {'; '.join(last)}): pick another object.layout_seed"
    )
