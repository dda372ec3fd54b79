"""Mesh extraction on an analytic sphere field: geometry, colours, labels, PLY, no-surface error."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import trimesh
from torch import nn

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.palette import class_colours
from neuralfeels_sem.mapping.mesh import extract_mesh, sdf_grid

NAMES = ["plastic", "metal"]


class AnalyticSphere(nn.Module):
    """Exact sphere SDF; material 1 (metal) above z = 0, 0 (plastic) below."""

    def __init__(self, radius: float, centre=(0.0, 0.0, 0.0)) -> None:
        super().__init__()
        self.radius = radius
        self.register_buffer("centre", torch.tensor(centre, dtype=torch.float32))

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.centre).norm(dim=1) - self.radius

    def predict_material(self, x: torch.Tensor) -> torch.Tensor:
        return (x[:, 2] > self.centre[2]).long()

    def material_logits(self, x: torch.Tensor) -> torch.Tensor:
        """Sure of its class except near the equator, where both classes are equally likely."""
        margin = 200.0 * (x[:, 2] - self.centre[2]).abs()
        return nn.functional.one_hot(self.predict_material(x), 2).float() * margin[:, None]


def test_sphere_mesh_is_closed_on_the_sphere_and_coloured_by_material() -> None:
    mesh = extract_mesh(AnalyticSphere(0.04), bound=0.06, resolution=48, class_names=NAMES)
    radii = np.linalg.norm(mesh.vertices, axis=1)
    assert np.abs(radii - 0.04).max() < 0.06 * 2 / 47 * 0.25  # within a quarter voxel
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * 0.04**3, rel=0.02)  # outward normals
    labels = mesh.vertex_attributes["label"]
    np.testing.assert_array_equal(labels, (mesh.vertices[:, 2] > 0).astype(np.int64))
    np.testing.assert_array_equal(mesh.visual.vertex_colors[:, :3], class_colours(NAMES)[labels])


def test_custom_palette_and_centre() -> None:
    centre = (0.01, -0.02, 0.03)
    palette = {"metal": (1, 2, 3)}
    mesh = extract_mesh(
        AnalyticSphere(0.03, centre),
        bound=0.05,
        resolution=32,
        class_names=NAMES,
        palette=palette,
        center=centre,
    )
    assert np.abs(np.linalg.norm(mesh.vertices - np.array(centre), axis=1) - 0.03).max() < 0.002
    top = mesh.vertex_attributes["label"] == 1
    assert np.all(mesh.visual.vertex_colors[top, :3] == (1, 2, 3))
    assert np.all(mesh.visual.vertex_colors[~top, :3] == class_colours(NAMES)[0])


def test_ply_round_trip_keeps_colours(tmp_path) -> None:
    mesh = extract_mesh(AnalyticSphere(0.04), bound=0.06, resolution=24, class_names=NAMES)
    path = tmp_path / "material_mesh.ply"
    mesh.export(path)
    loaded = trimesh.load(path, process=False)
    np.testing.assert_allclose(loaded.vertices, mesh.vertices, atol=1e-6)
    np.testing.assert_array_equal(loaded.visual.vertex_colors, mesh.visual.vertex_colors)


def test_vertices_carry_the_material_uncertainty_into_the_ply(tmp_path) -> None:
    """1 on the equator (both classes equally likely), near 0 towards the poles."""
    mesh = extract_mesh(AnalyticSphere(0.04), bound=0.06, resolution=24, class_names=NAMES)
    uncertainty = mesh.vertex_attributes["uncertainty"]
    z = mesh.vertices[:, 2]
    assert uncertainty.min() >= 0.0 and uncertainty.max() <= 1.0
    assert uncertainty[np.abs(z) > 0.03].max() < 0.05
    assert uncertainty[np.argmin(np.abs(z))] > 0.9  # the vertex nearest the equator
    path = tmp_path / "material_mesh.ply"
    mesh.export(path)
    loaded = trimesh.load(path, process=False)
    ply_vertices = loaded.metadata["_ply_raw"]["vertex"]["data"]
    np.testing.assert_allclose(ply_vertices["uncertainty"], uncertainty, atol=1e-6)


@pytest.mark.parametrize("radius", [0.2, -1.0])
def test_no_zero_crossing_is_a_no_data_error(radius: float) -> None:
    """All inside (sphere bigger than the cube) or all outside: no surface to extract."""
    with pytest.raises(NoDataError, match="no zero crossing"):
        extract_mesh(AnalyticSphere(radius), bound=0.06, resolution=16, class_names=NAMES)


def test_sdf_grid_axes_and_values() -> None:
    grid, axis = sdf_grid(AnalyticSphere(0.01), bound=0.05, resolution=11)
    assert grid.shape == (11, 11, 11)
    np.testing.assert_allclose(axis, np.linspace(-0.05, 0.05, 11))
    assert grid[5, 5, 5] == pytest.approx(-0.01)
    assert grid[10, 5, 5] == pytest.approx(0.04)
