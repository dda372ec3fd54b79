"""Batched forward pass: uint8 images in, class probabilities out."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.perception.classifier.transforms import normalize, to_tensor


@torch.inference_mode()
def predict_probs(
    model: nn.Module,
    images: np.ndarray,
    mean: Sequence[float],
    std: Sequence[float],
    device: torch.device,
    batch_size: int = 64,
) -> np.ndarray:
    """(N, S, S, 3) uint8, already at the model's input size -> (N, C) float32 probabilities."""
    # eval() walks every submodule: skip it for a model already in eval mode (a frozen
    # TorchScript model, model.trace_for_cpu, has no `training` flag at all)
    if getattr(model, "training", False):
        model.eval()
    out = []
    for start in range(0, len(images), batch_size):
        x = normalize(to_tensor(images[start : start + batch_size]).to(device), mean, std)
        out.append(torch.softmax(model(x).float(), dim=1).cpu().numpy())
    return np.concatenate(out) if out else np.zeros((0, 0), dtype=np.float32)
