"""Coarse-to-fine SDF sampling gives the same surface as the dense grid."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.mapping.mesh import sdf_grid


class TwoSpheres(nn.Module):
    """Analytic SDF: union of two spheres (a thin neck between them tests the margin)."""

    def __init__(self) -> None:
        super().__init__()
        self.scale = nn.Parameter(torch.ones(()))

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        a = (x - torch.tensor([0.02, 0.0, 0.0])).norm(dim=-1) - 0.025
        b = (x + torch.tensor([0.025, 0.01, 0.0])).norm(dim=-1) - 0.018
        return self.scale * torch.minimum(a, b)


def test_coarse_to_fine_matches_dense_near_the_surface() -> None:
    field = TwoSpheres()
    dense, axis = sdf_grid(field, 0.06, 64, coarse_step=1)
    fast, axis_fast = sdf_grid(field, 0.06, 64, coarse_step=4)
    np.testing.assert_array_equal(axis, axis_fast)
    assert np.array_equal(np.sign(dense), np.sign(fast))
    cell = axis[1] - axis[0]
    near = np.abs(dense) < 2 * cell
    np.testing.assert_allclose(fast[near], dense[near], atol=1e-6)
    # Most of the volume was never queried at full resolution (that is the point).
    assert (fast != dense).mean() > 0.5


def test_small_grids_fall_back_to_dense() -> None:
    field = TwoSpheres()
    dense, _ = sdf_grid(field, 0.06, 12, coarse_step=1)
    fast, _ = sdf_grid(field, 0.06, 12, coarse_step=4)
    np.testing.assert_array_equal(dense, fast)


def _truncated_sphere_field(steps: int = 100) -> nn.Module:
    """A field trained like the mapper's: the SDF target is only known within +-5 mm, so
    far from the surface it stays small (a distance margin would never prune it)."""
    from neuralfeels_sem.fields import FieldAdam, SemanticField
    from neuralfeels_sem.fields.hash_grid import HashGridConfig
    from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig

    torch.manual_seed(0)
    config = SemanticFieldConfig(num_classes=2, encoding=HashGridConfig(log2_table_size=14))
    field = SemanticField(config, bound=0.06)
    opt = FieldAdam(field.parameters(), lr=1e-2)
    g = torch.Generator().manual_seed(0)
    for _ in range(steps):
        x = (torch.rand(1024, 3, generator=g) * 2 - 1) * 0.06
        target = ((x - torch.tensor([0.005, 0.0, 0.0])).norm(dim=1) - 0.03).clamp(-0.005, 0.005)
        loss = (field.sdf(x) - target).abs().mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    return field


def test_pruned_grid_gives_the_dense_mesh_of_a_trained_field() -> None:
    from skimage.measure import marching_cubes

    field = _truncated_sphere_field()
    dense, _ = sdf_grid(field, 0.06, 64, coarse_step=1)
    assert np.abs(dense).max() < 0.02  # small everywhere: the old distance test kept it all
    fast, _ = sdf_grid(field, 0.06, 64, coarse_step=4)
    v_dense, f_dense, _, _ = marching_cubes(dense, 0.0)
    v_fast, f_fast, _, _ = marching_cubes(fast, 0.0)
    np.testing.assert_array_equal(v_fast, v_dense)
    np.testing.assert_array_equal(f_fast, f_dense)
    assert (fast != dense).mean() > 0.5  # most of the cube was answered by the coarse pass
