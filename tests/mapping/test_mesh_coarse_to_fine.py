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
