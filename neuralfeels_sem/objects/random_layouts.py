"""Material layouts of the generated benchmark objects: 2-4 materials in drawn regions.

The first drawn material is the body; every other one takes a region of one kind:
- `patch`: a ball centred on the surface cuts a roundish patch out of it (as patchwork's);
- `band`: a slab across one of the object's axes (as kitchen_tool's grip band);
- `half`: everything on one side of a plane through the middle (a two-tone object);
- `insert`: a small ellipsoid on the surface, about one DIGIT press (as patchwork's badge).
Inserts are applied last, so they stay whole on top of larger regions. The generator
(random_object.py) checks the result and redraws an object whose regions hide a material
or leave a sliver.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from neuralfeels_sem.objects import sdf as S
from neuralfeels_sem.objects.regions import Region

REGION_KINDS = ("patch", "band", "half", "insert")
# Inserts last (they must not be painted over); the larger regions in drawn order.
_PAINT_ORDER = {"patch": 0, "band": 0, "half": 0, "insert": 1}


@dataclass(frozen=True)
class Layout:
    base_material: str
    regions: list[Region]
    kinds: list[str]  # region kind of each material after the base, in drawn order
    materials: list[str]  # every drawn material, base first


def _surface_point(mesh: trimesh.Trimesh, rng: np.random.Generator) -> np.ndarray:
    # Marching-cubes vertices are close to uniform over the area, so a vertex is a fair draw.
    return np.asarray(mesh.vertices[rng.integers(len(mesh.vertices))], dtype=np.float64)


def _patch(mesh: trimesh.Trimesh, rng: np.random.Generator) -> S.SDF:
    radius = rng.uniform(0.25, 0.45) * float(mesh.extents.max())
    return S.sphere(tuple(_surface_point(mesh, rng)), radius)


def _band(mesh: trimesh.Trimesh, rng: np.random.Generator) -> S.SDF:
    # Across the longest axis more often: a band round a long object is what a tool has.
    axis = int(rng.choice(3, p=mesh.extents / mesh.extents.sum()))
    extent = float(mesh.extents[axis])
    centre = float(mesh.bounds.mean(axis=0)[axis] + rng.uniform(-0.25, 0.25) * extent)
    half_width = rng.uniform(0.1, 0.2) * extent
    return lambda p: np.abs(p[:, axis] - centre) - half_width


def _half(mesh: trimesh.Trimesh, rng: np.random.Generator) -> S.SDF:
    normal = rng.normal(size=3)
    normal /= np.linalg.norm(normal)
    offset = rng.uniform(-0.15, 0.15) * float(mesh.extents @ np.abs(normal))
    centre = mesh.bounds.mean(axis=0)
    return lambda p: (p - centre) @ normal - offset


def _insert(mesh: trimesh.Trimesh, rng: np.random.Generator) -> S.SDF:
    # 1.6-2.4 cm across: one press of the 1.8 x 2.4 cm gel covers most of it.
    radii = tuple(rng.uniform(0.008, 0.012, size=3))
    return S.ellipsoid(tuple(_surface_point(mesh, rng)), radii)


_DRAW = {"patch": _patch, "band": _band, "half": _half, "insert": _insert}


def draw_layout(mesh: trimesh.Trimesh, pool: Sequence[str], rng: np.random.Generator) -> Layout:
    """2-4 distinct materials from `pool` (at most its size) and a region for each but the first."""
    count = int(rng.integers(2, min(4, len(pool)) + 1))
    materials = [str(m) for m in rng.choice(np.asarray(pool), size=count, replace=False)]
    kinds = [str(rng.choice(REGION_KINDS)) for _ in materials[1:]]
    drawn = [(kind, Region(_DRAW[kind](mesh, rng), m)) for kind, m in zip(kinds, materials[1:])]
    drawn.sort(key=lambda pair: _PAINT_ORDER[pair[0]])  # stable: drawn order within a rank
    return Layout(materials[0], [region for _, region in drawn], kinds, materials)
