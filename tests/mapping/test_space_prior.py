"""SpaceCarvingPrior: carving along rays, hull labels, reservoir, resume."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from neuralfeels_sem.mapping.losses import space_prior_loss
from neuralfeels_sem.mapping.mapper import MapperConfig
from neuralfeels_sem.mapping.space_prior import OUTSIDE, SOLID, SpaceCarvingPrior


def _sphere_points(radius: float, n: int, seed: int = 0) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return radius * v / np.linalg.norm(v, axis=1, keepdims=True)


def test_carving_marks_the_ray_up_to_the_stop_and_nothing_behind() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=20)  # 1 cm voxels
    origin = np.array([0.5, 0.005, 0.005])  # far outside the cube, on +x
    end = np.array([[0.0, 0.005, 0.005]])
    prior.carve(origin, end, stop_before=0.02)
    carved_x = np.nonzero(prior.carved[:, 10, 10])[0]
    # Voxel i covers x in [-0.1 + 0.01 i, -0.09 + 0.01 i): the ray stops at x = 0.02.
    assert carved_x.min() == 12 and carved_x.max() == 19
    assert prior.carved.sum() == len(carved_x)  # only that row of voxels


def test_rays_missing_the_cube_carve_nothing() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=16)
    prior.carve(np.array([0.5, 0.5, 0.5]), np.array([[0.5, 0.5, 0.2]]), stop_before=0.005)
    assert not prior.carved.any()


def test_labels_inside_hull_solid_outside_hull_or_carved_outside() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=32)
    prior.add_surface(_sphere_points(0.05, 2000))
    prior.update_hull()
    assert prior.ready
    points = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.08], [0.03, 0.0, 0.0]])
    assert prior.label(points).tolist() == [SOLID, OUTSIDE, SOLID]
    # A ray down the x axis into the sphere carves the +x part of the interior.
    prior.carve(np.array([0.5, 0.0, 0.0]), np.array([[0.0, 0.0, 0.0]]), stop_before=0.015)
    assert prior.label(points).tolist() == [SOLID, OUTSIDE, OUTSIDE]


def test_sample_keeps_clear_of_observed_surface() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=32)
    surface = _sphere_points(0.05, 4000)
    prior.add_surface(surface)
    prior.update_hull()
    g = torch.Generator().manual_seed(0)
    x, sign, floor = prior.sample(4000, 0.01, g, torch.device("cpu"), margin=0.0)
    r = x.norm(dim=1)
    assert len(x) > 1000 and x.shape == (len(sign), 3) and floor.shape == sign.shape
    assert ((r - 0.05).abs() > 0.0095).all()  # within 1 cm of the sphere: dropped
    assert (sign[r < 0.04] == SOLID).all() and (sign[r > 0.06] == OUTSIDE).all()
    assert (floor == 0).all()  # margin 0: the sign alone


def test_sample_floors_outside_points_at_their_distance_from_the_hull() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=32)
    prior.add_surface(_sphere_points(0.05, 4000))
    prior.update_hull()
    g = torch.Generator().manual_seed(0)
    x, sign, floor = prior.sample(4000, 0.01, g, torch.device("cpu"), margin=0.02)
    r = x.norm(dim=1)
    # Outside a hull of 4000 points on the sphere, the distance to the hull is within a
    # fraction of a millimetre of the distance to the sphere (its facets are that small).
    outside = r > 0.06
    assert torch.allclose(floor[outside], (r[outside] - 0.05).clamp(max=0.02), atol=5e-4)
    assert (floor[r < 0.04] == 0).all() and floor.max() == pytest.approx(0.02)
    with pytest.raises(ValueError, match="margin"):
        prior.sample(10, 0.01, g, torch.device("cpu"), margin=-0.01)


def test_degenerate_points_give_no_hull() -> None:
    prior = SpaceCarvingPrior(bound=0.1)
    flat = np.random.default_rng(0).uniform(-0.05, 0.05, (100, 3))
    flat[:, 2] = 0.0
    prior.add_surface(flat)
    prior.update_hull()
    assert not prior.ready
    with pytest.raises(ValueError, match="no hull"):
        prior.label(np.zeros((1, 3)))


def test_reservoir_is_capped_and_spread_over_all_points() -> None:
    prior = SpaceCarvingPrior(bound=0.1, max_hull_points=500)
    first = np.zeros((500, 3), np.float32)
    second = np.ones((4500, 3), np.float32)
    prior.add_surface(first)
    prior.add_surface(second)
    assert prior.hull_points.shape == (500, 3) and prior.points_seen == 5000
    share_second = prior.hull_points[:, 0].mean()
    assert 0.8 < share_second < 0.97  # about 90 % of the points seen came second


def test_state_round_trip() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=16, seed=3)
    prior.add_surface(_sphere_points(0.05, 300))
    prior.carve(np.array([0.5, 0.0, 0.0]), np.array([[0.0, 0.0, 0.0]]), 0.005)
    prior.update_hull()
    other = SpaceCarvingPrior(bound=0.1, resolution=16, seed=99)
    other.load_state_dict(prior.state_dict())
    assert np.array_equal(other.carved, prior.carved)
    assert np.array_equal(other.hull_points, prior.hull_points) and other.ready
    more = _sphere_points(0.05, 50, seed=1)
    prior.add_surface(more)
    other.add_surface(more)
    assert np.array_equal(other.hull_points, prior.hull_points)


def test_bad_arguments_raise() -> None:
    with pytest.raises(ValueError, match="bound"):
        SpaceCarvingPrior(bound=0.0)
    with pytest.raises(ValueError, match="space_prior_margin=-0.001 must be >= 0"):
        MapperConfig(num_classes=2, space_prior_margin=-0.001)
    with pytest.raises(ValueError, match="match"):
        space_prior_loss(torch.zeros(3), torch.zeros(2))


def test_space_prior_loss_is_a_sign_hinge() -> None:
    sdf = torch.tensor([-0.01, 0.02, -0.01, 0.02])
    sign = torch.tensor([OUTSIDE, OUTSIDE, SOLID, SOLID])
    assert torch.allclose(space_prior_loss(sdf, sign), torch.tensor([0.01, 0.0, 0.0, 0.02]))
    # A floor lifts the outside points' target; solid points keep theirs at zero.
    floor = torch.full((4,), 0.03)
    expected = torch.tensor([0.04, 0.01, 0.0, 0.02])
    assert torch.allclose(space_prior_loss(sdf, sign, floor), expected)


def _carved_by_points(prior: SpaceCarvingPrior, origin: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Reference: every half-voxel point of every ray as one array, then its voxels."""
    ray = ends - origin
    length = np.linalg.norm(ray, axis=1)
    direction = ray / length[:, None]
    lo, hi = prior.center - prior.bound, prior.center + prior.bound
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - origin) / direction, (hi - origin) / direction
    t_enter = np.nan_to_num(np.minimum(t0, t1), nan=-np.inf).max(axis=1).clip(min=0.0)
    t_exit = np.minimum(np.nan_to_num(np.maximum(t0, t1), nan=np.inf).min(axis=1), length - 0.005)
    carved = np.zeros_like(prior.carved)
    for start, stop, d in zip(t_enter, t_exit, direction):
        t = start + 0.5 * prior.voxel_size * np.arange(200)
        idx = prior._voxel_index(origin + t[t <= stop][:, None] * d)
        carved[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    return carved


def test_carving_marks_the_voxels_of_every_half_voxel_step() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=16, ray_stride=1)
    origin = np.array([0.3, -0.2, 0.25])
    ends = np.random.default_rng(0).uniform(-0.08, 0.08, (300, 3))
    prior.carve(origin, ends, stop_before=0.005)
    assert prior.carved.any() and not prior.carved.all()
    np.testing.assert_array_equal(prior.carved, _carved_by_points(prior, origin, ends))


def test_labels_equal_the_facet_inequalities_on_random_points() -> None:
    prior = SpaceCarvingPrior(bound=0.1, resolution=32)
    prior.add_surface(_sphere_points(0.05, 3000) * [1.0, 0.6, 1.3])
    prior.update_hull()
    prior.carve(np.array([0.4, 0.1, 0.0]), _sphere_points(0.02, 50), stop_before=0.005)
    points = np.random.default_rng(1).uniform(-0.1, 0.1, (5000, 3))
    idx = prior._voxel_index(points)
    outside = prior.carved[idx[:, 0], idx[:, 1], idx[:, 2]] | (
        points @ prior.facets[:, :3].T + prior.facets[:, 3] > 1e-12
    ).any(axis=1)
    labels = prior.label(points)
    assert {OUTSIDE, SOLID} <= set(labels.tolist())
    np.testing.assert_array_equal(labels, np.where(outside, OUTSIDE, SOLID))


def test_the_mapper_rebuilds_the_hull_every_hull_every_frames(monkeypatch) -> None:
    """space_prior_hull_every=3: the hull is rebuilt on frames 0, 3, 6 (and whenever there
    is none yet), the reservoir still growing on every frame."""
    from neuralfeels_sem.mapping.space_prior import SpaceCarvingPrior
    from tests.mapping.synthetic import small_mapper, sphere_frames

    rebuilt = []
    update = SpaceCarvingPrior.update_hull
    monkeypatch.setattr(
        SpaceCarvingPrior,
        "update_hull",
        lambda self, *index: rebuilt.append(self.points_seen) or update(self, *index),
    )
    mapper = small_mapper(space_prior_hull_every=3, steps_per_frame=1, warmup_steps=1)
    for frame, labels in sphere_frames(8, touches_per_frame=1):
        mapper.add_frame(frame, labels)
    seen = mapper.memory.space_prior.points_seen
    assert len(rebuilt) == 3 and rebuilt == sorted(set(rebuilt)) and rebuilt[-1] < seen
    with pytest.raises(ValueError, match="space_prior_hull_every"):
        small_mapper(space_prior_hull_every=0)


def test_with_frames_skipped_the_hull_is_still_rebuilt_once_a_block() -> None:
    """At realtime pace the mapper skips frames: with space_prior_hull_every=5 and only
    frames 2, 7, 12, ... mapped (never a multiple of 5) the hull is rebuilt on the first
    frame mapped of each block of 5 indices, not just once."""
    from tests.mapping.synthetic import small_mapper, sphere_frames

    mapper = small_mapper(space_prior_hull_every=5, steps_per_frame=1, warmup_steps=1)
    built = []
    for k, (frame, labels) in enumerate(sphere_frames(4, touches_per_frame=1)):
        frame.index = 2 + 5 * k
        mapper.add_frame(frame, labels)
        built.append(mapper.memory.space_prior.built_at)
    assert built == [2, 7, 12, 17]
