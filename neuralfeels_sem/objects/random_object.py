"""`object=random object.seed=K`: a generated object nobody tuned on (the unseen benchmark).

One seed gives one object: a shape family (random_shapes.py; drawn from the seed unless
`object.family` forces one), a size, and a layout of 2-4 materials (random_layouts.py),
with the shipped objects' regions of interest: seams between materials and the face it
rests on are ignored. A draw that fails its own checks (`problems`) is never accepted: the
object is drawn again from the next sub-seed, deterministically, and the sub-seed used is
recorded (`GeneratedObject.generation`, logged). Seeds below 1000 are for development;
1000-1019 are the evaluation set (`experiment=unseen_objects`), see docs/objects.md.
"""

from __future__ import annotations

import functools
import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import trimesh

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.objects import disk_cache, layout_draw
from neuralfeels_sem.objects import sdf as S
from neuralfeels_sem.objects.layout_draw import layout_problems, paint
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.objects.materials import mass_and_friction, names_to_labels
from neuralfeels_sem.objects.random_layouts import draw_layout
from neuralfeels_sem.objects.random_shapes import FAMILIES

log = logging.getLogger(__name__)

EVALUATION_SEEDS_FROM = 1000  # seeds from here on are the evaluation set, never tuned on
SIZE_RANGE_M = (0.05, 0.20)  # largest extent of every generated object
TARGET_FACES = 20_000  # as the shipped objects (the 1 mm tactile renderer sees smooth geometry)
_DRAW_BOX_M = 0.2  # families draw inside +-this box before scaling
# The cache key hashes these (procedural.py: the seam and resting-face widths).
_GENERATOR_SOURCES = (
    "random_object.py",
    "random_shapes.py",
    "random_layouts.py",
    "layout_draw.py",
    "sdf.py",
    "regions.py",
    "procedural.py",
)


@dataclass
class GeneratedObject(MaterialObject):
    """A MaterialObject with how it was generated (seed, sub-seed, family, size, layout)."""

    generation: dict = field(default_factory=dict)


def _scaled(shape: S.SDF, scale: float) -> S.SDF:
    return lambda p: scale * shape(p / scale)


def _draw_mesh(rng: np.random.Generator, family: str, target_faces: int) -> trimesh.Trimesh:
    """The family's solid scaled to a drawn size, cut flat underneath if drawn so, centred."""
    draw = FAMILIES[family](rng)
    coarse = S.mesh_sdf(draw.shape, (-_DRAW_BOX_M,) * 3, (_DRAW_BOX_M,) * 3, 0.005)
    scale = float(rng.uniform(*draw.size_range)) / float(coarse.extents.max())
    shape = _scaled(draw.shape, scale)
    lower, upper = coarse.bounds * scale
    if draw.flat_bottom > 0:
        z_cut = lower[2] + draw.flat_bottom * (upper[2] - lower[2])
        shape = S.smooth_intersection(shape, S.half_space_above(z_cut), k=0.002)
    margin = 0.006  # the coarse grid may cut the surface short by up to a cell
    mesh = S.mesh_sdf_with_faces(shape, lower - margin, upper + margin, target_faces)
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    return mesh


def problems(mesh: trimesh.Trimesh, names: np.ndarray, materials: Sequence[str]) -> list[str]:
    """Why a drawn object cannot be used (empty: it can): its shape's checks, then its layout's."""
    found = []
    if not mesh.is_watertight:
        found.append("not watertight")
    size = float(mesh.extents.max())
    if not SIZE_RANGE_M[0] <= size <= SIZE_RANGE_M[1]:
        found.append(f"largest extent {100 * size:.1f} cm outside {SIZE_RANGE_M} m")
    return found + layout_problems(mesh, names, materials)


def draw_object(
    seed: int, sub_seed: int, family: str, pool: Sequence[str], target_faces: int = TARGET_FACES
) -> tuple[trimesh.Trimesh, np.ndarray, dict]:
    """One draw: (mesh, per-face material names, generation record). Unchecked."""
    rng = np.random.default_rng([seed, sub_seed])
    mesh = _draw_mesh(rng, family, target_faces)
    layout = draw_layout(mesh, pool, rng)
    names = paint(mesh, layout)
    record = {
        "seed": seed,
        "sub_seed": sub_seed,
        "family": family,
        "size_m": round(float(mesh.extents.max()), 4),
        "materials": layout.materials,
        "regions": layout.kinds,
    }
    return mesh, names, record


def build_arrays(
    seed: int, family: str, pool: Sequence[str], target_faces: int = TARGET_FACES
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """The first draw from sub-seed 0 on that passes `problems`: (vertices, faces, names, record)."""
    last: list[str] = []
    for sub_seed in range(layout_draw.MAX_SUB_SEEDS):
        mesh, names, record = draw_object(seed, sub_seed, family, pool, target_faces)
        last = problems(mesh, names, record["materials"])
        if not last:
            return np.asarray(mesh.vertices), np.asarray(mesh.faces), names, record
        log.info("object=random seed %d sub-seed %d redrawn: %s", seed, sub_seed, "; ".join(last))
    raise DataError(
        f"object.seed={seed} (family {family}) failed its checks in {layout_draw.MAX_SUB_SEEDS} draws "
        f"(last: {'; '.join(last)}): pick another object.seed"
    )


_CACHE_KEYS = ("vertices", "faces", "names", "record")


@functools.cache
def _generate(seed: int, family: str, pool: tuple[str, ...]) -> tuple:
    """`build_arrays`, cached in-process and on disk (data/objects/), read-only arrays."""
    path = disk_cache.entry_path(f"random-{seed}-{family}-{'_'.join(pool)}", _GENERATOR_SOURCES)
    cached = disk_cache.load(path, _CACHE_KEYS)
    if cached is not None:
        arrays = (cached["vertices"], cached["faces"], cached["names"])
        record = json.loads(str(cached["record"]))
    else:
        *arrays, record = build_arrays(seed, family, pool)
        disk_cache.save(path, dict(zip(_CACHE_KEYS, (*arrays, np.array(json.dumps(record))))))
    for array in arrays:
        array.flags.writeable = False
    return (*arrays, record)


def development_seeds(text: str) -> list[int]:
    """Object seeds from "K" or "A-B" (both ends included); a ValueError when one is an
    evaluation seed, never data to train or choose settings on."""
    low, _, high = text.partition("-")
    try:
        seeds = list(range(int(low), int(high or low) + 1))
    except ValueError:
        raise ValueError(f"object seeds {text!r}: write K or A-B, e.g. 20-59") from None
    if not seeds or max(seeds) >= EVALUATION_SEEDS_FROM:
        raise ValueError(
            f"object seeds {text!r}: seeds from {EVALUATION_SEEDS_FROM} are the evaluation set, "
            f"never data to train or choose settings on; use seeds below {EVALUATION_SEEDS_FROM}"
        )
    return seeds


def family_of(seed: int, family: str | None) -> str:
    """The forced family, or the one seed `seed` draws; ConfigError for an unknown name."""
    if family is None:
        return list(FAMILIES)[int(np.random.default_rng(seed).integers(len(FAMILIES)))]
    if family not in FAMILIES:
        raise ConfigError(
            f"object.family={family!r} is unknown: pick one of {list(FAMILIES)} or null (drawn from the seed)"
        )
    return family


def _material_pool(materials: Sequence[str] | None, class_names: tuple[str, ...]) -> tuple:
    pool = tuple(class_names if materials is None else materials)
    unknown = [m for m in pool if m not in class_names]
    if unknown:
        raise ConfigError(
            f"object.materials has {unknown}, not in materials={list(class_names)}: pick from those"
        )
    if len(set(pool)) < 2:
        raise ConfigError(
            f"object=random needs at least two different materials to lay out, got {list(pool)}: "
            "list two or more in object.materials (null: every class in materials)"
        )
    return tuple(dict.fromkeys(pool))  # drop repeats, keep the order (the draw depends on it)


def make_random_object(
    seed: int,
    class_names: Sequence[str],
    family: str | None = None,
    materials: Sequence[str] | None = None,
    name: str | None = None,
    aruco: object = None,
) -> GeneratedObject:
    """Generated object `seed` with face labels indexing `class_names`.

    `materials` (default: every class) are the ones the layout draws from; `aruco` is read
    by sensor=real from the config and accepted here only so the config instantiates.
    """
    class_names = tuple(class_names)
    family = family_of(seed, family)
    pool = _material_pool(materials, class_names)
    vertices, faces, names, record = _generate(int(seed), family, pool)
    log.info("object=random: %s", record)
    labels = names_to_labels(names, class_names, what=f"object=random seed {seed}")
    mesh = trimesh.Trimesh(vertices.copy(), faces.copy(), process=False)
    mass, friction = mass_and_friction(
        float(mesh.volume), np.asarray(mesh.area_faces), labels, class_names, record["materials"][0]
    )
    return GeneratedObject(
        name=name or f"random_{seed}",
        mesh=mesh,
        face_labels=labels,
        class_names=class_names,
        mass_kg=mass,
        friction=friction,
        generation=dict(record),
    )
