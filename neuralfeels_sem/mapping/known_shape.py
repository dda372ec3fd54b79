"""Signed distance of a ground-truth mesh as a dense grid, for `mapping.pose=track_known_shape`.

Exact mesh queries (trimesh's signed distance) cost seconds per thousand far points; the
tracker needs tens of evaluations per frame. So the SDF is sampled once on a cube grid
around the mesh and trilinearly interpolated in torch (differentiable in the points).
Grid values: in a band next to the surface, where the tracker's residuals live, the
signed distance to the plane of the nearest of dense surface samples (exact to the
micrometre); farther out, the distance to the band (to about a cell) with the sign of
what the band shell encloses (a hole fill).
Grids are cached in memory and on disk (data/sdf_grids/, keyed by the mesh's bytes).
"""

from __future__ import annotations

import hashlib
import logging

import numpy as np
import torch
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree
from torch import Tensor

from neuralfeels_sem.utils import paths

log = logging.getLogger(__name__)

_MEMORY: dict[str, tuple[np.ndarray, np.ndarray, float]] = {}


def _key(mesh: trimesh.Trimesh, resolution: int, padding: float) -> str:
    digest = hashlib.sha256()
    digest.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    digest.update(f"{resolution}-{padding}-v1".encode())
    return digest.hexdigest()[:16]


def mesh_sdf_grid(
    mesh: trimesh.Trimesh, resolution: int = 96, padding: float = 0.2, use_disk: bool = True
) -> tuple[np.ndarray, np.ndarray, float]:
    """(grid (R, R, R) float32 indexed [x, y, z], origin (3,) of grid[0, 0, 0], spacing in m)."""
    if resolution < 8:
        raise ValueError(f"resolution={resolution} must be >= 8")
    if padding < 0:
        raise ValueError(f"padding={padding} must be >= 0")
    key = _key(mesh, resolution, padding)
    if key in _MEMORY:
        return _MEMORY[key]
    path = paths.CACHE_DIR / "sdf_grids" / f"{key}.npz" if use_disk else None
    if path is not None and path.is_file():
        try:
            with np.load(path) as data:
                result = (data["grid"], data["origin"], float(data["spacing"]))
            _MEMORY[key] = result
            return result
        except (OSError, ValueError, KeyError) as exc:
            log.warning("ignoring unreadable SDF grid cache %s (%s)", path, exc)
    result = _compute(mesh, resolution, padding)
    _MEMORY[key] = result
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, grid=result[0], origin=result[1], spacing=result[2])
            tmp.replace(path)
        except OSError as exc:
            log.warning("could not cache the SDF grid at %s (%s)", path, exc)
    return result


def _compute(
    mesh: trimesh.Trimesh, resolution: int, padding: float
) -> tuple[np.ndarray, np.ndarray, float]:
    lo, hi = mesh.bounds
    centre = 0.5 * (lo + hi)
    side = float((hi - lo).max()) * (1.0 + 2.0 * padding)
    spacing = side / (resolution - 1)
    origin = centre - 0.5 * side
    axis = np.arange(resolution) * spacing
    gx, gy, gz = np.meshgrid(axis + origin[0], axis + origin[1], axis + origin[2], indexing="ij")
    grid_pts = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    # Surface samples about spacing/3 apart: their distance is within ~spacing/6 of the truth.
    count = int(np.clip(mesh.area / (spacing / 3.0) ** 2, 20000, 400000))
    samples, faces = trimesh.sample.sample_surface(mesh, count, seed=0)
    # Only the band needs the samples (a bounded query is fast; an unbounded one over
    # the whole grid took half a minute); farther out, distance to the band suffices.
    band_width = 3.0 * spacing
    dist, nearest = cKDTree(samples).query(grid_pts, distance_upper_bound=band_width, workers=-1)
    band = np.isfinite(dist).reshape((resolution,) * 3)
    # The shell is several cells thick, so it is closed and filling it finds the interior.
    inside = ndimage.binary_fill_holes(band) & ~band
    # In the band: signed point-to-plane distance to the nearest sample's face, exact up
    # to the curvature over the sample gap (micrometres), and the side of the surface.
    idx = np.flatnonzero(band.ravel())
    near = nearest[idx]
    flat = np.zeros(len(grid_pts))
    flat[idx] = np.einsum("ij,ij->i", grid_pts[idx] - samples[near], mesh.face_normals[faces[near]])
    # Outside the band: via the nearest band cell, |p - b| + |sdf(b)| (about a cell off).
    _, to_band = ndimage.distance_transform_edt(~band, return_indices=True)
    nearest_band = np.ravel_multi_index(tuple(to_band.reshape(3, -1)), band.shape)
    far = np.linalg.norm(grid_pts - grid_pts[nearest_band], axis=1) + np.abs(flat[nearest_band])
    rest = ~band.ravel()
    flat[rest] = np.where(inside.ravel()[rest], -far[rest], far[rest])
    return flat.reshape((resolution,) * 3).astype(np.float32), origin, float(spacing)


class GridSdf:
    """Trilinear interpolation of a grid SDF in torch; points outside the grid get the
    distance to the grid box added, so the gradient still points back toward the object."""

    def __init__(self, grid: np.ndarray, origin: np.ndarray, spacing: float) -> None:
        grid = np.asarray(grid, dtype=np.float32)
        if grid.ndim != 3 or min(grid.shape) < 2:
            raise ValueError(f"grid must be (X, Y, Z) with each >= 2, got {grid.shape}")
        if np.asarray(origin).shape != (3,) or spacing <= 0:
            raise ValueError(f"origin must be (3,) and spacing > 0, got {origin}, {spacing}")
        # grid_sample reads (D, H, W) = (x, y, z) and takes coordinates ordered (z, y, x).
        self.volume = torch.from_numpy(grid)[None, None]
        self.origin = torch.as_tensor(np.asarray(origin, dtype=np.float32))
        self.extent = torch.tensor([(n - 1) * spacing for n in grid.shape], dtype=torch.float32)

    @classmethod
    def of_mesh(cls, mesh: trimesh.Trimesh, resolution: int = 96, padding: float = 0.2) -> GridSdf:
        return cls(*mesh_sdf_grid(mesh, resolution, padding))

    def __call__(self, x: Tensor) -> Tensor:
        """(N, 3) object-frame metres -> (N,) signed distance in metres."""
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {tuple(x.shape)}")
        rel = x.to(torch.float32) - self.origin
        clamped = torch.minimum(torch.maximum(rel, torch.zeros_like(rel)), self.extent)
        outside = (rel - clamped).norm(dim=1)
        coords = (2.0 * clamped / self.extent - 1.0).flip(1)
        value = torch.nn.functional.grid_sample(
            self.volume, coords[None, :, None, None, :], mode="bilinear", align_corners=True
        )
        return value.reshape(-1) + outside
