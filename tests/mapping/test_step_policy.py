"""Optimiser steps per frame by how much of it the field does not explain (mapping/step_policy.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from neuralfeels_sem.mapping.step_policy import steps_for, surprise
from neuralfeels_sem.perception.touch import TouchLabel
from tests.mapping.synthetic import small_mapper, sphere_frames


class PlaneField(nn.Module):
    """SDF = z (metres); class 1 above z = 0, class 0 below."""

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return x[:, 2]

    def material_logits(self, x: torch.Tensor) -> torch.Tensor:
        return torch.stack([-x[:, 2], x[:, 2]], dim=1)


def _touch(label: int, usable: bool = True) -> TouchLabel:
    return TouchLabel("index", contact=True, label=label, confidence=0.9, low_confidence=not usable)


def test_steps_run_linearly_from_the_minimum_to_the_full_count() -> None:
    assert [steps_for(s, 1, 5) for s in (0.0, 0.25, 0.5, 1.0)] == [1, 2, 3, 5]
    with pytest.raises(ValueError, match="surprise share"):
        steps_for(1.5, 1, 5)


def test_surprise_is_the_larger_share_of_unexplained_geometry_and_wrong_labels() -> None:
    field, trunc, cpu = PlaneField(), 0.005, torch.device("cpu")
    on_plane = np.zeros((400, 3), np.float32)
    off_plane = on_plane + [0.0, 0.0, 0.02]
    half = np.concatenate([on_plane[:200], off_plane[:200]])
    assert surprise(field, {"camera": on_plane}, {}, trunc, cpu) == 0.0
    assert surprise(field, {"camera": off_plane}, {}, trunc, cpu) == 1.0
    assert surprise(field, {"camera": half}, {}, trunc, cpu) == pytest.approx(0.5, abs=0.02)
    above, below = np.full((8, 3), 0.01, np.float32), np.full((8, 3), -0.01, np.float32)
    points = {"camera": on_plane, "index": above, "middle": below}
    right = {"index": _touch(1), "middle": _touch(0)}
    one_wrong = {"index": _touch(1), "middle": _touch(1)}
    assert surprise(field, points, right, trunc, cpu) == 0.0
    assert surprise(field, points, one_wrong, trunc, cpu) == 0.5
    # A touch the classifier did not label is not judged.
    assert surprise(field, points, {"middle": _touch(1, usable=False)}, trunc, cpu) == 0.0


def test_a_field_that_explains_a_frame_spends_fewer_steps_on_it() -> None:
    frames = sphere_frames(4, touches_per_frame=2)
    small = {"camera_rays": 32, "tactile_rays": 16, "material_points": 16, "space_prior_points": 0}
    mapper = small_mapper(
        steps_policy="surprise", steps_per_frame=8, min_steps_per_frame=1, warmup_steps=60, **small
    )
    first, labels = frames[0]
    mapper.add_frame(first, labels)
    assert mapper.log.steps == 60  # the warm-up block is the policy's to leave alone
    mapper.add_frame(first, labels)  # the same frame again: the field knows it by now
    repeated = mapper.log.steps - 60
    fixed = small_mapper(steps_per_frame=8, warmup_steps=60, **small)
    fixed.add_frame(first, labels)
    fixed.add_frame(first, labels)
    assert 1 <= repeated < fixed.log.steps - 60 == 8
