"""Loss functions: exact values on hand-made cases and a numeric gradient check."""

from __future__ import annotations

import math

import pytest
import torch

from neuralfeels_sem.mapping.losses import (
    batch_bound,
    eikonal_loss,
    freespace_loss,
    material_loss,
    truncated_sdf_loss,
)


def test_batch_bound_is_min_of_ray_distance_and_nearest_surface_point() -> None:
    surface = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    x = torch.tensor([[0.0, 0.3, 0.0], [0.9, 0.0, 0.0], [5.0, 0.0, 0.0]])
    s = torch.tensor([0.5, -0.05, 10.0])
    torch.testing.assert_close(batch_bound(x, s, surface), torch.tensor([0.3, 0.05, 4.0]))
    # Chunking does not change the result.
    torch.testing.assert_close(batch_bound(x, s, surface, chunk=1), batch_bound(x, s, surface))


def test_batch_bound_matches_brute_force_on_a_ray_batch() -> None:
    g = torch.Generator().manual_seed(0)
    surface = torch.rand(384, 3, generator=g) * 0.1
    x = surface.repeat_interleave(9, 0) + torch.randn(3456, 3, generator=g) * 0.005
    s = torch.full((len(x),), 1.0)  # the ray distance never binds: the nearest point decides
    brute = torch.cdist(x.double(), surface.double()).min(dim=1).values.float()
    torch.testing.assert_close(batch_bound(x, s, surface), brute, rtol=0, atol=1e-7)


def test_truncated_sdf_loss_signs_the_bound_by_side() -> None:
    sdf = torch.tensor([0.002, 0.002, 0.0, -0.001])
    s = torch.tensor([0.003, -0.003, 0.0, -0.001])
    bound = torch.tensor([0.002, 0.002, 0.0, 0.001])
    torch.testing.assert_close(
        truncated_sdf_loss(sdf, s, bound), torch.tensor([0.0, 0.004, 0.0, 0.0])
    )


def test_freespace_loss_is_zero_inside_bounds_and_linear_outside() -> None:
    sdf = torch.tensor([0.01, -0.02, 0.08, 0.05])
    bound = torch.tensor([0.05, 0.05, 0.05, 0.05])
    torch.testing.assert_close(freespace_loss(sdf, bound), torch.tensor([0.0, 0.02, 0.03, 0.0]))


def test_eikonal_loss_values() -> None:
    grad = torch.tensor([[1.0, 0.0, 0.0], [0.0, 3.0, 4.0], [0.0, 0.0, 0.0]])
    torch.testing.assert_close(eikonal_loss(grad), torch.tensor([0.0, 16.0, 1.0]))
    with pytest.raises(ValueError):
        eikonal_loss(torch.zeros(3, 2))


def test_material_loss_weights_cross_entropy_by_confidence() -> None:
    logits = torch.tensor([[2.0, 0.0], [0.0, 0.0]])
    labels = torch.tensor([0, 1])
    weights = torch.tensor([0.5, 0.0])
    expected = 0.5 * -math.log(math.exp(2) / (math.exp(2) + 1))
    torch.testing.assert_close(
        material_loss(logits, labels, weights), torch.tensor([expected, 0.0])
    )
    with pytest.raises(ValueError):
        material_loss(logits, labels[:1], weights)


def test_losses_pass_a_numeric_gradient_check() -> None:
    g = torch.Generator().manual_seed(0)
    sdf = (torch.rand(6, generator=g, dtype=torch.float64) - 0.3).requires_grad_(True)
    s = torch.tensor([0.1, -0.2, 0.3, -0.1, 0.2, 0.4], dtype=torch.float64)
    bound = torch.full((6,), 0.7, dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda v: truncated_sdf_loss(v, s, bound).sum(), (sdf,))
    assert torch.autograd.gradcheck(lambda v: freespace_loss(v, bound).sum(), (sdf,))
    grad = torch.rand(5, 3, generator=g, dtype=torch.float64).add(0.1).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda v: eikonal_loss(v).sum(), (grad,))
    logits = torch.rand(5, 3, generator=g, dtype=torch.float64).requires_grad_(True)
    labels, weights = torch.tensor([0, 1, 2, 1, 0]), torch.rand(5, generator=g, dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda v: material_loss(v, labels, weights).sum(), (logits,))
