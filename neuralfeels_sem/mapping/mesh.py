"""Mesh extraction: marching cubes on the field's SDF, vertices coloured by predicted material."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
import trimesh
from skimage.measure import marching_cubes
from torch import nn

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.palette import class_colours
from neuralfeels_sem.fields.material_uncertainty import normalised_entropy


def _device(field: nn.Module) -> torch.device:
    return next(iter(field.parameters()), torch.zeros(())).device


@torch.no_grad()
def _evaluate(fn, points: np.ndarray, device: torch.device, chunk: int) -> np.ndarray:
    out = [
        fn(torch.as_tensor(c, dtype=torch.float32, device=device)).cpu().numpy()
        for c in np.array_split(points, max(1, len(points) // chunk))
    ]
    return np.concatenate(out) if out else np.zeros(0)


def sdf_grid(
    field: nn.Module,
    bound: float,
    resolution: int,
    center: Sequence[float] = (0.0, 0.0, 0.0),
    chunk: int = 65536,
    coarse_step: int = 4,
    dilation_cells: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """SDF on a resolution^3 grid spanning center +- bound; returns (grid, axis coordinates).

    Coarse to fine, because a dense 128^3-256^3 query dominates evaluation time: the SDF is
    first sampled every `coarse_step` grid points; only coarse cells whose corners change
    sign, and the cells within `dilation_cells` of one, are evaluated at full resolution.
    Elsewhere the grid holds the nearest coarse value, which has the right sign, so
    marching cubes finds the same surface (`coarse_step=1`: dense). A test on distance
    (|SDF| below a margin) would not prune a trained field: its SDF is only trained
    within the truncation band and stays small far from the surface. What this misses is
    a surface wholly inside one coarse cell and its neighbours without a coarse corner on
    the other side: a blob under about `coarse_step` grid cells across.
    """
    if resolution < 2 or bound <= 0:
        raise ValueError(f"need resolution >= 2 and bound > 0, got {resolution}, {bound}")
    axis = np.linspace(-bound, bound, resolution)
    offset = np.asarray(center, dtype=np.float64)
    device = _device(field)

    def query(ix: np.ndarray, iy: np.ndarray, iz: np.ndarray) -> np.ndarray:
        points = np.stack([axis[ix], axis[iy], axis[iz]], axis=-1) + offset
        return _evaluate(field.sdf, points, device, chunk)

    if coarse_step <= 1 or resolution < 4 * coarse_step:
        gx, gy, gz = np.meshgrid(*(np.arange(resolution),) * 3, indexing="ij")
        return query(gx.ravel(), gy.ravel(), gz.ravel()).reshape((resolution,) * 3), axis
    nodes = np.unique(np.append(np.arange(0, resolution, coarse_step), resolution - 1))
    cx, cy, cz = np.meshgrid(nodes, nodes, nodes, indexing="ij")
    coarse = query(cx.ravel(), cy.ravel(), cz.ravel()).reshape((len(nodes),) * 3)
    crossing = _dilate(_sign_change_cells(coarse), dilation_cells)
    # Nearest coarse node of every fine index, then exact values in the crossing cells.
    nearest = np.abs(np.arange(resolution)[:, None] - nodes[None, :]).argmin(axis=1)
    grid = coarse[np.ix_(nearest, nearest, nearest)].copy()
    fx, fy, fz = np.nonzero(_fine_points_of_cells(crossing, nodes, resolution))
    if len(fx):
        grid[fx, fy, fz] = query(fx, fy, fz)
    return grid, axis


def _sign_change_cells(values: np.ndarray) -> np.ndarray:
    """Cells (n-1)^3 of a node grid n^3 whose 8 corners are not all of one strict sign."""
    n = values.shape[0]
    corners = [
        values[i : n - 1 + i, j : n - 1 + j, k : n - 1 + k]
        for i in (0, 1)
        for j in (0, 1)
        for k in (0, 1)
    ]
    low, high = np.minimum.reduce(corners), np.maximum.reduce(corners)
    return (low <= 0) & (high >= 0)


def _dilate(mask: np.ndarray, cells: int) -> np.ndarray:
    """Boolean mask grown by `cells` in every direction (26-connected)."""
    for _ in range(cells):
        grown = mask.copy()
        for axis in range(3):
            shifted = np.zeros_like(grown)
            lead = [slice(None)] * 3
            trail = [slice(None)] * 3
            lead[axis], trail[axis] = slice(1, None), slice(None, -1)
            shifted[tuple(lead)] |= grown[tuple(trail)]
            shifted[tuple(trail)] |= grown[tuple(lead)]
            grown |= shifted
        mask = grown
    return mask


def _fine_points_of_cells(cells: np.ndarray, nodes: np.ndarray, resolution: int) -> np.ndarray:
    """resolution^3 mask of the fine grid points on or inside the marked coarse cells.

    Per axis, `member[p, c]` says whether fine index p lies in coarse cell c (its two
    nodes included); a point is kept when the product of its three axes' memberships
    meets a marked cell (three small tensor contractions instead of a loop over cells).
    """
    fine = np.arange(resolution)[:, None]
    member = ((fine >= nodes[None, :-1]) & (fine <= nodes[None, 1:])).astype(np.float32)
    marked = cells.astype(np.float32)
    out = np.tensordot(member, marked, axes=([1], [0]))  # (R, C, C)
    out = np.tensordot(out, member, axes=([1], [1]))  # (R, C, R)
    out = np.tensordot(out, member, axes=([1], [1]))  # (R, R, R)
    return out > 0


def extract_mesh(
    field: nn.Module,
    bound: float,
    resolution: int,
    class_names: Sequence[str],
    palette: dict[str, Sequence[int]] | None = None,
    center: Sequence[float] = (0.0, 0.0, 0.0),
) -> trimesh.Trimesh:
    """Zero level set of the field's SDF in the cube center +- bound (object frame, metres).

    Vertex colours come from `palette` (material name -> RGB; core.palette's colours for names
    it lacks or when None) of
    each vertex's predicted class; the class index is the vertex attribute `label` and the
    normalised entropy of the material branch (0-1) the vertex attribute `uncertainty`.
    Raises NoDataError when the SDF does not cross zero inside the cube (an untrained field).
    """
    grid, axis = sdf_grid(field, bound, resolution, center)
    if not np.isfinite(grid).all() or grid.min() >= 0 or grid.max() <= 0:
        raise NoDataError(
            f"the field's SDF has no zero crossing within +-{bound} m (range {grid.min():.4f}..{grid.max():.4f}); "
            "it has not learned a surface yet: feed it more frames or more optimiser steps"
        )
    spacing = float(axis[1] - axis[0])
    verts, faces, _, _ = marching_cubes(grid, level=0.0, spacing=(spacing,) * 3)
    verts = verts - bound + np.asarray(center, dtype=np.float64)
    device = _device(field)
    logits = _evaluate(field.material_logits, verts, device, 65536)
    labels = logits.argmax(axis=1).astype(np.int64)
    table = class_colours(class_names)
    for i, name in enumerate(class_names):
        if palette and name in palette:
            table[i] = np.asarray(palette[name], dtype=np.uint8)[:3]
    colours = np.concatenate([table[labels], np.full((len(labels), 1), 255, np.uint8)], axis=1)
    # skimage winds faces so normals point toward increasing values: outward for an SDF.
    mesh = trimesh.Trimesh(vertices=verts, faces=faces, vertex_colors=colours, process=False)
    mesh.vertex_attributes["label"] = labels
    uncertainty = normalised_entropy(torch.as_tensor(logits)).numpy().astype(np.float32)
    mesh.vertex_attributes["uncertainty"] = uncertainty
    return mesh
