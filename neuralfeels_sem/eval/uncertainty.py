"""How well the material map's uncertainty predicts where the map is wrong (docs/evaluation.md).

On the ground-truth surface samples of the matching figures, with p the softmax of the
material branch at a sample:
- uncertainty = normalised entropy H(p) / log(C) (0-1, fields/material_uncertainty.py);
- error = argmax p differs from the ground-truth class (the samples `matching_pct` counts wrong);
- `auroc`: area under the ROC curve of uncertainty as a detector of error (1.0: every wrong
  sample is more uncertain than every right one; 0.5: no better than chance);
- `ece`: expected calibration error of confidence = max p over ECE_BINS equal-width bins of
  [0, 1]: sum over bins of (share of samples in the bin) * |accuracy - mean confidence|.
Both are None, with a note, when every sample is right or every one is wrong.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from scipy.stats import rankdata
from torch import nn

from neuralfeels_sem.core.geometry import transform_points
from neuralfeels_sem.fields.material_uncertainty import material_probabilities

ECE_BINS = 15
ProbabilityPredictor = Callable[[np.ndarray], np.ndarray]


def entropy_of_probabilities(probs: np.ndarray) -> np.ndarray:
    """(N, C) probabilities -> (N,) entropy / log(C), in [0, 1]."""
    probs = np.asarray(probs, dtype=np.float64)
    if probs.ndim != 2 or probs.shape[1] < 2:
        raise ValueError(f"probabilities must have shape (N, C) with C >= 2, got {probs.shape}")
    safe = np.where(probs > 0, probs, 1.0)  # 0 log 0 = 0
    return np.clip(-(probs * np.log(safe)).sum(axis=1) / np.log(probs.shape[1]), 0.0, 1.0)


def auroc(scores: np.ndarray, positive: np.ndarray) -> float | None:
    """Area under the ROC curve of `scores` ranking `positive` samples above the others.

    Mann-Whitney form with average ranks, so tied scores count one half. None when only
    one class of outcome is present (the area is undefined).
    """
    scores = np.asarray(scores, dtype=np.float64)
    positive = np.asarray(positive, dtype=bool)
    if scores.shape != positive.shape or scores.ndim != 1:
        raise ValueError(f"scores {scores.shape} and outcomes {positive.shape} must be equal 1-D")
    n_pos = int(positive.sum())
    n_neg = len(positive) - n_pos
    if n_pos == 0 or n_neg == 0:
        return None
    ranks = rankdata(scores)  # average ranks of ties
    return float((ranks[positive].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def expected_calibration_error(
    confidence: np.ndarray, correct: np.ndarray, bins: int = ECE_BINS
) -> float:
    """Sum over equal-width confidence bins of (bin share) * |bin accuracy - bin mean confidence|."""
    confidence = np.asarray(confidence, dtype=np.float64)
    correct = np.asarray(correct, dtype=bool)
    if confidence.shape != correct.shape or confidence.ndim != 1 or len(confidence) == 0:
        raise ValueError(f"confidence {confidence.shape} and outcomes {correct.shape} must match")
    if bins < 1:
        raise ValueError(f"bins={bins} must be >= 1")
    # Bin b holds (b/bins, (b+1)/bins]; a confidence of exactly 0 goes to the first bin.
    index = np.clip(np.ceil(confidence * bins).astype(np.int64) - 1, 0, bins - 1)
    ece = 0.0
    for b in np.unique(index):
        inside = index == b
        ece += inside.mean() * abs(correct[inside].mean() - confidence[inside].mean())
    return float(ece)


def uncertainty_scores(probs: np.ndarray, labels: np.ndarray) -> dict:
    """The `uncertainty` block of metrics.json from (N, C) probabilities and (N,) true classes."""
    probs = np.asarray(probs, dtype=np.float64)
    labels = np.asarray(labels)
    if probs.ndim != 2 or probs.shape[0] != labels.shape[0]:
        raise ValueError(f"probabilities {probs.shape} do not match labels {labels.shape}")
    entropy = entropy_of_probabilities(probs)
    wrong = probs.argmax(axis=1) != labels
    out = {
        "auroc": auroc(entropy, wrong),
        "ece": expected_calibration_error(probs.max(axis=1), ~wrong),
        "ece_bins": ECE_BINS,
        "mean_entropy": float(entropy.mean()),
        "mean_entropy_correct": float(entropy[~wrong].mean()) if (~wrong).any() else None,
        "mean_entropy_wrong": float(entropy[wrong].mean()) if wrong.any() else None,
        "error_share": float(wrong.mean()),
        "samples": len(labels),
    }
    if out["auroc"] is None:
        outcome = "wrong" if wrong.all() else "right"
        out["note"] = (
            f"every one of the {len(labels)} samples is {outcome}: "
            "the AUROC of uncertainty vs error is undefined"
        )
    return out


def probability_predictor(
    field: nn.Module, field_T_gt: np.ndarray | None = None, chunk: int = 65536
) -> ProbabilityPredictor:
    """(N,3) ground-truth object-frame points -> (N, C) softmax of the field's material branch."""
    device = next(field.parameters()).device

    def predict(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        if len(points) == 0:
            return np.zeros((0, field.num_classes))
        if field_T_gt is not None:
            points = transform_points(field_T_gt, points)
        x = torch.as_tensor(points, dtype=torch.float32, device=device)
        parts = [material_probabilities(field, c) for c in torch.split(x, chunk)]
        return torch.cat(parts).cpu().numpy().astype(np.float64)

    return predict
