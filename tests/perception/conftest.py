"""Fixtures shared by the perception tests."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from neuralfeels_sem.perception.classifier.checkpoint import save_checkpoint
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD
from tests.perception.synthetic_tactile import CLASSES


@pytest.fixture(scope="module")
def untrained_checkpoint(tmp_path_factory) -> Path:
    """A classifier checkpoint for CLASSES with seeded random weights (32 px input)."""
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("ckpt") / "classifier.pt"
    save_checkpoint(path, build_model(4), CLASSES, 32, list(IMAGENET_MEAN), list(IMAGENET_STD))
    return path
