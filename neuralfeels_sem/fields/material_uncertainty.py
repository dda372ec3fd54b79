"""Predictive uncertainty of the material branch: normalised entropy of its softmax.

H(p) / log(C) lies in [0, 1]: 0 when one class takes all the probability, 1 when the C
classes are equally likely. It lives with the field because both the mesh extraction
(mapping) and the scoring (eval) need it, and those layers do not import each other.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor


def normalised_entropy(logits: Tensor) -> Tensor:
    """(N, C) class logits -> (N,) entropy of their softmax divided by log(C), in [0, 1]."""
    if logits.ndim != 2 or logits.shape[1] < 2:
        raise ValueError(f"logits must have shape (N, C) with C >= 2, got {tuple(logits.shape)}")
    log_p = torch.log_softmax(logits.float(), dim=-1)
    # p log p is 0 where p underflows to 0: exp(log_p) is 0 there and log_p finite (or -inf).
    plogp = torch.where(log_p.isfinite(), log_p.exp() * log_p, torch.zeros_like(log_p))
    return (-plogp.sum(dim=-1) / math.log(logits.shape[1])).clamp(0.0, 1.0)


@torch.no_grad()
def material_probabilities(field, x: Tensor) -> Tensor:
    """Softmax of the field's material logits at x (N, 3) metres: (N, C)."""
    return torch.softmax(field.material_logits(x).float(), dim=-1)
