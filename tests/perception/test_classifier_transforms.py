"""Preprocessing is shared by training and inference; augmentation is seeded and bounded."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from neuralfeels_sem.perception.classifier.transforms import (
    augment,
    normalize,
    resize_batch,
    to_tensor,
)


def test_resize_and_tensor_layout() -> None:
    images = np.zeros((2, 320, 240, 3), np.uint8)
    images[0, :, :, 0] = 255
    batch = resize_batch(images, 64)
    assert batch.shape == (2, 64, 64, 3) and batch.dtype == np.uint8
    x = to_tensor(batch)
    assert x.shape == (2, 3, 64, 64)
    assert float(x[0, 0].min()) == 1.0 and float(x[0, 1].max()) == 0.0 and float(x[1].max()) == 0.0
    with pytest.raises(ValueError):
        resize_batch(np.zeros((1, 32, 32), np.uint8), 16)


def test_normalize_exact() -> None:
    x = torch.full((1, 3, 2, 2), 0.5)
    y = normalize(x, [0.5, 0.25, 0.0], [0.5, 0.25, 0.5])
    assert torch.allclose(y[0, :, 0, 0], torch.tensor([0.0, 1.0, 1.0]))


def test_augment_is_identity_at_zero_strength() -> None:
    x = torch.rand(3, 3, 32, 32)
    y = augment(
        x.clone(),
        torch.Generator().manual_seed(0),
        rotation_deg=0,
        brightness=0,
        contrast=0,
        color_gain=0,
    )
    assert torch.equal(x, y)


def test_augment_is_seeded_bounded_and_changes_images() -> None:
    x = torch.rand(4, 3, 32, 32)
    a = augment(x.clone(), torch.Generator().manual_seed(3))
    b = augment(x.clone(), torch.Generator().manual_seed(3))
    c = augment(x.clone(), torch.Generator().manual_seed(4))
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert a.min() >= 0 and a.max() <= 1 and not torch.allclose(a, x)


def test_brightness_only_scales_within_range() -> None:
    x = torch.full((64, 3, 8, 8), 0.5)
    y = augment(
        x,
        torch.Generator().manual_seed(0),
        rotation_deg=0,
        brightness=0.2,
        contrast=0,
        color_gain=0,
    )
    scale = y[:, 0, 0, 0] / 0.5
    assert scale.min() >= 0.8 - 1e-6 and scale.max() <= 1.2 + 1e-6 and scale.std() > 0.05
    # one factor per image, the same for every pixel and channel
    assert torch.allclose(y, y[:, :1, :1, :1].expand_as(y))
