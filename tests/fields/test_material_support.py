"""The map's nearest-label fill beyond mapping.mapper.fill_m of every trained touch point."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from neuralfeels_sem.fields.material_support import (
    FADE_M,
    VOXEL_M,
    MaterialSupport,
    current_support,
)
from neuralfeels_sem.mapping.mapper import MapperConfig
from tests.mapping.synthetic import sphere_frames, sphere_surface, true_label
from tests.mapping.test_mapper import make_mapper


def _support(fill_m: float = 0.01) -> MaterialSupport:
    points = torch.tensor([[0.0, 0.0, 0.0], [0.001, 0.0, 0.0], [0.1, 0.0, 0.0]])
    return MaterialSupport(points, torch.tensor([0, 0, 2]), 3, fill_m)


def test_beyond_fill_m_the_nearest_label_wins_less_surely_the_farther() -> None:
    support = _support()
    x = torch.tensor([[0.005, 0.0, 0.0], [0.03, 0.0, 0.0], [0.08, 0.0, 0.0], [0.095, 0, 0]])
    field = torch.tensor([[0.1, 0.8, 0.1], [0.1, 0.8, 0.1], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    out = support.blend(x, field)
    torch.testing.assert_close(out[0], field[0])  # 5 mm from a press: the field's own
    torch.testing.assert_close(out[3], field[3])
    assert out[1].argmax() == 0 and out[2].argmax() == 2  # the nearest press' label
    torch.testing.assert_close(out.sum(dim=1), torch.ones(4))
    s = np.exp(-(0.02 - 0.01) / FADE_M)  # 2 cm from the third press, 1 cm past fill_m
    expected = torch.tensor([(1 - s) / 3, (1 - s) / 3, s + (1 - s) / 3], dtype=torch.float32)
    torch.testing.assert_close(out[2], expected)
    assert out[1].max() < out[2].max()  # 2.9 cm from the nearest press: less sure


def test_the_trained_points_are_thinned_to_a_voxel_each_labelled_by_most() -> None:
    points = torch.tensor([[0.0001, 0, 0], [0.0002, 0, 0], [0.0003, 0, 0], [0.05, 0, 0]])
    support = MaterialSupport(points, torch.tensor([1, 1, 0, 2]), 3, 0.01)
    support.blend(torch.zeros(1, 3), torch.full((1, 3), 1 / 3))  # the first read builds it
    assert len(support.points) == 2 and VOXEL_M > 0.0003
    order = np.argsort(support.points[:, 0])
    np.testing.assert_array_equal(support.labels[order], [1, 2])
    np.testing.assert_allclose(support.points[order][0], [0.0002, 0.0, 0.0], atol=1e-9)


def test_no_support_points_leave_the_field_alone_and_bad_input_is_refused() -> None:
    empty = MaterialSupport(torch.zeros(0, 3), torch.zeros(0, dtype=torch.long), 3, 0.01)
    probs = torch.full((2, 3), 1 / 3)
    assert empty.blend(torch.ones(2, 3), probs) is probs
    with pytest.raises(ValueError, match="2 support points but 1 labels"):
        MaterialSupport(torch.zeros(2, 3), torch.zeros(1, dtype=torch.long), 3, 0.01)
    with pytest.raises(ValueError, match="fill_m"):
        MaterialSupport(torch.zeros(1, 3), torch.zeros(1, dtype=torch.long), 3, 0.0)
    bad = MaterialSupport(torch.zeros(1, 3), torch.tensor([5]), 3, 0.01)
    with pytest.raises(ValueError, match=r"labels must be in \[0, 3\)"):
        bad.blend(torch.ones(1, 3), torch.full((1, 3), 1 / 3))
    with pytest.raises(ValueError, match="mapping.mapper.fill_m"):
        MapperConfig(fill_m=0.0)


def test_a_support_is_made_anew_only_when_the_touch_tensors_change() -> None:
    points, labels = torch.zeros(1, 3), torch.zeros(1, dtype=torch.long)
    first = current_support(None, points, labels, 3, 0.01)
    assert current_support(first, points, labels, 3, 0.01) is first
    assert current_support(first, points.clone(), labels, 3, 0.01) is not first


def test_the_mapper_hands_its_field_the_trained_points_and_the_map_reads_them() -> None:
    # Touches on one side of the sphere only: far from them the branch extrapolates.
    mapper = make_mapper(steps_per_frame=4, warmup_steps=10)
    off = make_mapper(steps_per_frame=4, warmup_steps=10, fill_m=None)
    for frame, labels in sphere_frames(3, touches_per_frame=4, camera=False):
        mapper.add_frame(frame, labels)
        off.add_frame(frame, labels)
    touch = mapper.memory.touches.tensors()
    assert mapper.field.support.source[0] is touch["labelled_points"]
    assert off.field.support is None
    surface = torch.tensor(sphere_surface(2000), dtype=torch.float32)
    with torch.no_grad():
        filled = mapper.field.predict_material(surface).numpy()
        plain = off.field.predict_material(surface).numpy()
    dist, nearest = mapper.field.support._tree.query(surface.numpy())
    far = dist > mapper.config.fill_m
    assert far.any() and (filled[far] == mapper.field.support.labels[nearest[far]]).all()
    assert (filled != plain).any()
    truth = true_label(surface.numpy())
    assert (filled == truth).mean() >= (plain == truth).mean() - 0.02
    # a copy of the field (as the background scorer takes) reads the same
    with torch.no_grad():
        np.testing.assert_array_equal(
            copy.deepcopy(mapper.field).predict_material(surface).numpy(), filled
        )


def test_a_restored_mapper_reads_with_its_touches_support() -> None:
    mapper = make_mapper(steps_per_frame=2, warmup_steps=2)
    for frame, labels in sphere_frames(2, touches_per_frame=4, camera=False):
        mapper.add_frame(frame, labels)
    restored = make_mapper(steps_per_frame=2, warmup_steps=2)
    assert restored.field.support is None  # nothing trained yet
    restored.load_state_dict(mapper.state_dict())
    torch.testing.assert_close(restored.field.support.source[0], mapper.field.support.source[0])
    surface = torch.tensor(sphere_surface(500), dtype=torch.float32)
    with torch.no_grad():
        np.testing.assert_array_equal(
            restored.field.predict_material(surface).numpy(),
            mapper.field.predict_material(surface).numpy(),
        )
