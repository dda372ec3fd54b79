"""Shape families of the generated benchmark objects (`object=random`): an SDF per draw.

Each family draws a smooth implicit solid from a numpy Generator, at a rough size; the
generator (random_object.py) then scales it to a drawn overall size and meshes it with
marching cubes, so every object is watertight by construction. Coordinates are metres, z
up; long shapes lie along y (as kitchen_tool does) so that the rig's default motion, a turn
about z then about y, brings both ends past the fingers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.objects import sdf as S


@dataclass(frozen=True)
class ShapeDraw:
    """A drawn solid and how the generator should finish it."""

    shape: S.SDF
    # Overall size range (largest extent, m) this family is scaled into.
    size_range: tuple[float, float]
    # Share of the height cut off flat underneath (the face it rests on, ignored); 0: none.
    flat_bottom: float


def _lying_along_y(f: S.SDF) -> S.SDF:
    """An upright shape (long axis z) laid down with its long axis along y."""
    return lambda p: f(p[:, [2, 0, 1]])


def _torus_about_x(centre: np.ndarray, major: float, minor: float) -> S.SDF:
    """A ring standing in the y-z plane (a handle on the side of a body)."""

    def f(p: np.ndarray) -> np.ndarray:
        q = p - centre
        return np.hypot(np.hypot(q[:, 1], q[:, 2]) - major, q[:, 0]) - minor

    return f


def blobby(rng: np.random.Generator) -> ShapeDraw:
    """A pebble or potato: 3-6 ellipsoids blended into one smooth body."""
    parts = [S.ellipsoid((0.0, 0.0, 0.0), tuple(rng.uniform(0.025, 0.04, size=3)))]
    for _ in range(rng.integers(2, 6)):
        centre = rng.uniform(-0.018, 0.018, size=3)
        parts.append(S.ellipsoid(tuple(centre), tuple(rng.uniform(0.012, 0.026, size=3))))
    flat = float(rng.choice([0.0, rng.uniform(0.08, 0.2)]))
    return ShapeDraw(S.smooth_union(parts, k=float(rng.uniform(0.006, 0.012))), (0.06, 0.11), flat)


def cylindrical(rng: np.random.Generator) -> ShapeDraw:
    """A can, bottle or turned part: 1-3 coaxial rounded cylinders stacked along z."""
    radius = rng.uniform(0.018, 0.032)
    z, parts = 0.0, []
    for _ in range(rng.integers(1, 4)):
        height = rng.uniform(0.02, 0.06)
        r = radius * rng.uniform(0.6, 1.1)
        parts.append(S.rounded_cylinder(z, z + height, r, min(0.004, 0.3 * r)))
        z += height * 0.9
    return ShapeDraw(S.smooth_union(parts, k=0.004), (0.06, 0.12), 0.0)


def boxy(rng: np.random.Generator) -> ShapeDraw:
    """A box with bevelled edges, sometimes with a second box fused on (an L or a step)."""
    half = rng.uniform(0.015, 0.035, size=3)
    bevel = float(rng.uniform(0.003, 0.4 * half.min()))
    parts = [S.rounded_box((0.0, 0.0, 0.0), tuple(half), bevel)]
    if rng.random() < 0.5:
        offset = rng.uniform(-1.0, 1.0, size=3) * half
        half2 = half * rng.uniform(0.5, 0.8, size=3)
        parts.append(S.rounded_box(tuple(offset), tuple(half2), min(bevel, 0.4 * half2.min())))
    return ShapeDraw(S.smooth_union(parts, k=0.002), (0.05, 0.11), 0.0)


def elongated(rng: np.random.Generator) -> ShapeDraw:
    """A tool or bar lying along y: a long capsule with a bulge at one or both ends."""
    length = rng.uniform(0.08, 0.12)
    radius = rng.uniform(0.012, 0.018)
    parts = [S.capsule((0.0, 0.0, 0.0), (0.0, 0.0, length), radius)]
    for end in rng.permutation([0.0, length])[: rng.integers(1, 3)]:
        parts.append(S.ellipsoid((0.0, 0.0, float(end)), tuple(rng.uniform(0.016, 0.024, size=3))))
    shape = _lying_along_y(S.smooth_union(parts, k=0.008))
    return ShapeDraw(shape, (0.12, 0.20), float(rng.uniform(0.1, 0.2)))


def handled(rng: np.random.Generator) -> ShapeDraw:
    """A mug or jug: an upright body with a ring handle on its side."""
    radius = rng.uniform(0.022, 0.032)
    height = rng.uniform(0.045, 0.07)
    if rng.random() < 0.5:
        body = S.rounded_cylinder(0.0, height, radius, 0.005)
    else:
        body = S.ellipsoid((0.0, 0.0, height / 2), (radius, radius, height / 2))
    major = rng.uniform(0.014, 0.02)
    handle = _torus_about_x(np.array([0.0, -radius - 0.3 * major, height / 2]), major, 0.005)
    return ShapeDraw(S.smooth_union([body, handle], k=0.004), (0.08, 0.13), 0.0)


def rimmed(rng: np.random.Generator) -> ShapeDraw:
    """A pot, jar or puck: a short cylinder with a raised rim round its top (and foot)."""
    radius = rng.uniform(0.024, 0.036)
    height = rng.uniform(0.025, 0.06)
    parts = [
        S.rounded_cylinder(0.0, height, radius, 0.004),
        S.torus(height - 0.004, radius, rng.uniform(0.003, 0.006)),
    ]
    if rng.random() < 0.5:
        parts.append(S.torus(0.004, radius, rng.uniform(0.003, 0.005)))
    return ShapeDraw(S.smooth_union(parts, k=0.003), (0.06, 0.10), 0.0)


FAMILIES: dict[str, Callable[[np.random.Generator], ShapeDraw]] = {
    "blobby": blobby,
    "cylindrical": cylindrical,
    "boxy": boxy,
    "elongated": elongated,
    "handled": handled,
    "rimmed": rimmed,
}
