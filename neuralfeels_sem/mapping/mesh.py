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
    margin_cells: float = 1.5,
) -> tuple[np.ndarray, np.ndarray]:
    """SDF on a resolution^3 grid spanning center +- bound; returns (grid, axis coordinates).

    Coarse to fine, because a dense 128^3-256^3 query dominates evaluation time: the SDF is
    first sampled every `coarse_step` grid points; only coarse cells whose corners change
    sign or come within `margin_cells` coarse-cell diagonals of zero are evaluated at full
    resolution. Elsewhere the grid holds the nearest coarse value, which has the right sign
    and is far from zero, so marching cubes finds the same surface (`coarse_step=1`: dense).
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
    corners = np.stack(
        [
            coarse[i : len(nodes) - 1 + i, j : len(nodes) - 1 + j, k : len(nodes) - 1 + k]
            for i in (0, 1)
            for j in (0, 1)
            for k in (0, 1)
        ]
    )
    margin = margin_cells * np.sqrt(3.0) * coarse_step * (axis[1] - axis[0])
    near = (np.abs(corners).min(axis=0) < margin) | (corners.min(axis=0) < 0) & (
        corners.max(axis=0) > 0
    )
    # Nearest coarse node of every fine index, then exact values in the cells near the surface.
    nearest = np.abs(np.arange(resolution)[:, None] - nodes[None, :]).argmin(axis=1)
    grid = coarse[np.ix_(nearest, nearest, nearest)].copy()
    mask = np.zeros((resolution,) * 3, dtype=bool)
    for i, j, k in zip(*np.nonzero(near)):
        mask[
            nodes[i] : nodes[i + 1] + 1, nodes[j] : nodes[j + 1] + 1, nodes[k] : nodes[k + 1] + 1
        ] = True
    fx, fy, fz = np.nonzero(mask)
    if len(fx):
        grid[fx, fy, fz] = query(fx, fy, fz)
    return grid, axis


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
