"""Ray samples: positions, signed distances and ranges are exactly what the contract says."""

from __future__ import annotations

import pytest
import torch

from neuralfeels_sem.mapping.sampling import (
    balanced_indices,
    label_groups,
    random_indices,
    sample_along_rays,
    subsample,
)


def rays(r: int = 50) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(1)
    surface = torch.randn(r, 3, generator=g) * 0.05
    direction = torch.nn.functional.normalize(torch.randn(r, 3, generator=g), dim=1)
    length = torch.rand(r, generator=g) * 0.2 + 0.01
    return surface, direction, length


def test_samples_lie_on_their_rays_with_the_right_distances() -> None:
    surface, direction, length = rays()
    out = sample_along_rays(
        surface, direction, length, 5, 4, 0.005, 0.05, torch.Generator().manual_seed(0)
    )
    assert len(out) == 50 * 10
    torch.testing.assert_close(
        out.x, surface[out.ray] - out.s.unsqueeze(1) * direction[out.ray], rtol=0, atol=1e-7
    )
    per_ray = out.s.reshape(50, 10)
    assert torch.all(per_ray[:, 0] == 0)  # the surface sample
    band = per_ray[:, 1:6]
    assert band.abs().max() <= 0.005 and (band < 0).any() and (band > 0).any()
    free = per_ray[:, 6:]
    far = torch.clamp(length, max=0.05).clamp_min(0.005).unsqueeze(1)
    assert torch.all(free >= 0.005) and torch.all(free <= far + 1e-7)
    assert torch.equal(out.free.reshape(50, 10)[:, 6:], torch.ones(50, 4, dtype=torch.bool))
    assert not out.free.reshape(50, 10)[:, :6].any()


def test_sampling_is_repeatable_with_the_same_generator() -> None:
    surface, direction, length = rays()
    a = sample_along_rays(
        surface, direction, length, 3, 3, 0.005, 0.05, torch.Generator().manual_seed(7)
    )
    b = sample_along_rays(
        surface, direction, length, 3, 3, 0.005, 0.05, torch.Generator().manual_seed(7)
    )
    assert torch.equal(a.x, b.x)


def test_bad_shapes_raise_value_error() -> None:
    surface, direction, length = rays()
    with pytest.raises(ValueError):
        sample_along_rays(surface, direction[:3], length, 1, 1, 0.005, 0.05, torch.Generator())
    with pytest.raises(ValueError):
        sample_along_rays(surface, direction, length, 1, 1, 0.01, 0.005, torch.Generator())


def test_subsample_and_random_indices() -> None:
    g = torch.Generator().manual_seed(0)
    keep = subsample(100, 10, g, replace_if_short=False)
    assert len(keep) == 10 and len(set(keep.tolist())) == 10
    assert torch.equal(subsample(5, 10, g, replace_if_short=False), torch.arange(5))
    short = subsample(5, 10, g, replace_if_short=True)
    assert len(short) == 10 and short.max() < 5
    assert len(subsample(0, 10, g, replace_if_short=True)) == 0
    idx = random_indices(7, 1000, g, torch.device("cpu"))
    assert idx.min() >= 0 and idx.max() <= 6 and len(torch.unique(idx)) == 7
    assert len(random_indices(0, 10, g, torch.device("cpu"))) == 0


def test_balanced_indices_give_each_material_an_equal_share() -> None:
    # 1000 points of one material, 10 of an insert, 90 of a third; class 1 absent.
    labels = torch.tensor([0] * 1000 + [2] * 10 + [3] * 90)[torch.randperm(1100)]
    g = torch.Generator().manual_seed(0)
    groups = label_groups(labels)
    idx = balanced_indices(groups, 30000, g, torch.device("cpu"))
    share = torch.bincount(labels[idx], minlength=4).float() / len(idx)
    assert share[1] == 0 and torch.allclose(share[[0, 2, 3]], torch.full((3,), 1 / 3), atol=0.02)
    assert len(torch.unique(idx[labels[idx] == 2])) == 10  # every insert point is drawn
    assert len(torch.unique(idx[labels[idx] == 0])) > 900  # uniform within a material
    empty = label_groups(torch.zeros(0, dtype=torch.long))
    assert len(balanced_indices(empty, 10, g, torch.device("cpu"))) == 0
    assert len(balanced_indices(groups, 0, g, torch.device("cpu"))) == 0


@pytest.mark.parametrize("power", [0.5, 1.0])
def test_tempered_shares_grow_with_the_point_count_to_the_power(power: float) -> None:
    labels = torch.tensor([0] * 1000 + [2] * 10 + [3] * 90)
    g = torch.Generator().manual_seed(1)
    idx = balanced_indices(label_groups(labels), 40000, g, torch.device("cpu"), power)
    share = torch.bincount(labels[idx], minlength=4).double() / len(idx)
    expected = torch.tensor([1000.0, 0.0, 10.0, 90.0], dtype=torch.float64) ** power
    expected[1] = 0.0
    assert torch.allclose(share, expected / expected.sum(), atol=0.01)
