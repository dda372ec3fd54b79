"""Held-out scoring of a tactile depth network: contact IoU and depth MAE, overall and per
finger (definitions: perception/tactile_depth_metrics.py)."""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.perception.tactile_depth_metrics import DepthCounts, depth_counts, summarise
from neuralfeels_sem.perception.tactile_depth_net.compose import Augmentation, compose_frames
from neuralfeels_sem.perception.tactile_depth_net.predict import DepthNetPredictor

EVAL_BATCH = 16


def score(
    predictor: DepthNetPredictor,
    change: np.ndarray,
    press_mm: np.ndarray,
    fingers: list[str],
    backgrounds: np.ndarray,
    augmentation: Augmentation,
    seed: int,
) -> dict:
    """Compose every sample once (background k % K, noise and drift from `seed`), predict,
    and sum the counts; {"overall": figures, "per_finger": {finger: figures}}."""
    rng = np.random.default_rng(seed)
    totals: dict[str, DepthCounts] = defaultdict(DepthCounts)
    for start in range(0, len(change), EVAL_BATCH):
        idx = np.arange(start, min(start + EVAL_BATCH, len(change)))
        bg = backgrounds[idx % len(backgrounds)]
        frames, given = compose_frames(change[idx].astype(np.float32), bg, rng, augmentation)
        predicted = predictor.predict(frames, given)
        for j, k in enumerate(idx):
            press = press_mm[k].astype(np.float32)
            gt = np.where(press > 0, GEL_DISTANCE_M - press / 1000.0, 0.0).astype(np.float32)
            totals[fingers[k]] += depth_counts(predicted[j], gt, press > 0)
    overall = sum(totals.values(), DepthCounts())
    return {
        "overall": _rounded(summarise(overall)),
        "per_finger": {f: _rounded(summarise(c)) for f, c in sorted(totals.items())},
    }


def _rounded(figures: dict) -> dict:
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in figures.items()}
