"""Signed-distance primitives and a marching-cubes mesher for the procedural objects.

Every primitive maps points (N, 3) in metres to signed distances (N,), negative
inside. Blended unions (`smooth_union`) are not exact distances but keep the zero
level set smooth, which is all the mesher and the region tests need.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh
from skimage.measure import marching_cubes

SDF = Callable[[np.ndarray], np.ndarray]


def sphere(center: tuple[float, float, float], radius: float) -> SDF:
    c = np.asarray(center, dtype=np.float64)
    return lambda p: np.linalg.norm(p - c, axis=-1) - radius


def ellipsoid(center: tuple[float, float, float], radii: tuple[float, float, float]) -> SDF:
    """Ellipsoid: zero on the surface, exact on the axes outside, negative inside."""
    c = np.asarray(center, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)

    def f(p: np.ndarray) -> np.ndarray:
        q = p - c
        k0 = np.linalg.norm(q / r, axis=-1)
        k1 = np.linalg.norm(q / (r * r), axis=-1)
        outside = k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)
        # Quilez's bound vanishes at the centre; inside use a scaled radial distance.
        return np.where(k0 >= 1.0, outside, (k0 - 1.0) * r.min())

    return f


def capsule(a: tuple[float, float, float], b: tuple[float, float, float], radius: float) -> SDF:
    pa0 = np.asarray(a, dtype=np.float64)
    ba = np.asarray(b, dtype=np.float64) - pa0

    def f(p: np.ndarray) -> np.ndarray:
        pa = p - pa0
        h = np.clip(pa @ ba / (ba @ ba), 0.0, 1.0)
        return np.linalg.norm(pa - h[:, None] * ba, axis=-1) - radius

    return f


def rounded_cylinder(z0: float, z1: float, radius: float, rounding: float) -> SDF:
    """Cylinder around the z axis from z0 to z1 with edges rounded by `rounding`."""
    zc, half = 0.5 * (z0 + z1), 0.5 * (z1 - z0)

    def f(p: np.ndarray) -> np.ndarray:
        d = np.stack(
            [
                np.hypot(p[:, 0], p[:, 1]) - radius + rounding,
                np.abs(p[:, 2] - zc) - half + rounding,
            ],
            axis=-1,
        )
        outside = np.linalg.norm(np.maximum(d, 0.0), axis=-1)
        return np.minimum(d.max(axis=-1), 0.0) + outside - rounding

    return f


def torus(z: float, major: float, minor: float) -> SDF:
    """Torus around the z axis at height z."""
    return lambda p: np.hypot(np.hypot(p[:, 0], p[:, 1]) - major, p[:, 2] - z) - minor


def rounded_box(
    center: tuple[float, float, float], half: tuple[float, float, float], rounding: float
) -> SDF:
    c = np.asarray(center, dtype=np.float64)
    h = np.asarray(half, dtype=np.float64) - rounding

    def f(p: np.ndarray) -> np.ndarray:
        q = np.abs(p - c) - h
        return (
            np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0) - rounding
        )

    return f


def half_space_below(z: float) -> SDF:
    """Everything with height <= z (intersect with it to cut a flat bottom or top)."""
    return lambda p: p[:, 2] - z


def half_space_above(z: float) -> SDF:
    return lambda p: z - p[:, 2]


def _smin(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum with blend radius k (k=0: plain min)."""
    if k <= 0:
        return np.minimum(a, b)
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def smooth_union(parts: list[SDF], k: float) -> SDF:
    def f(p: np.ndarray) -> np.ndarray:
        d = parts[0](p)
        for part in parts[1:]:
            d = _smin(d, part(p), k)
        return d

    return f


def smooth_intersection(a: SDF, b: SDF, k: float) -> SDF:
    return lambda p: -_smin(-a(p), -b(p), k)


def smooth_difference(a: SDF, b: SDF, k: float) -> SDF:
    """a minus b."""
    return lambda p: -_smin(-a(p), b(p), k)


def displaced(base: SDF, offset: Callable[[np.ndarray], np.ndarray], max_offset: float) -> SDF:
    """Move the surface outwards by offset(p) in [0, max_offset] metres (small, smooth).

    The offset is only evaluated within 4 mm of the base surface: farther out it
    cannot change the sign, so the zero level set and the cells around it are exact.
    """

    def f(p: np.ndarray) -> np.ndarray:
        d = base(p)
        near = np.abs(d) < max_offset + 0.004
        d[near] -= offset(p[near])
        return d

    return f


def mesh_sdf(
    sdf: SDF, lower: np.ndarray, upper: np.ndarray, spacing: float, chunk: int = 1 << 20
) -> trimesh.Trimesh:
    """Watertight triangle mesh of the zero level set of `sdf` inside the box [lower, upper].

    The box must contain the whole solid: the grid is padded with one layer of outside
    cells, so the surface always closes.
    """
    lower = np.asarray(lower, dtype=np.float64) - 2 * spacing
    upper = np.asarray(upper, dtype=np.float64) + 2 * spacing
    counts = np.ceil((upper - lower) / spacing).astype(int) + 1
    axes = [lower[i] + spacing * np.arange(counts[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    values = np.concatenate([sdf(grid[i : i + chunk]) for i in range(0, len(grid), chunk)])
    values = values.reshape(counts)
    if values.min() >= 0:
        raise ValueError("mesh_sdf: the solid is empty inside the box")
    border = np.concatenate(
        [values[[0, -1]].ravel(), values[:, [0, -1]].ravel(), values[:, :, [0, -1]].ravel()]
    )
    if border.min() <= 0:
        raise ValueError("mesh_sdf: the solid touches the box; enlarge the bounds")
    verts, faces, _, _ = marching_cubes(values, level=0.0, spacing=(spacing,) * 3)
    mesh = trimesh.Trimesh(verts + lower, faces, process=True)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    # skimage orients faces by the field's gradient; make the normals point outwards.
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def mesh_sdf_with_faces(
    sdf: SDF, lower: np.ndarray, upper: np.ndarray, target_faces: int, min_spacing: float = 0.0008
) -> trimesh.Trimesh:
    """`mesh_sdf` with the grid spacing picked so the mesh has about `target_faces` faces.

    A coarse 4 mm pass measures the area; marching cubes makes about 3 faces per
    spacing^2 of surface. Spacing stays within [min_spacing, 2 mm] so that a 1 mm
    tactile renderer still sees smooth geometry.
    """
    coarse = mesh_sdf(sdf, lower, upper, 0.004)
    spacing = float(np.sqrt(3.0 * coarse.area / target_faces))
    return mesh_sdf(sdf, lower, upper, float(np.clip(spacing, min_spacing, 0.002)))
