"""Tactile depth against the simulator's ground truth: contact IoU and depth error.

For one reading, `depth_counts(pred_depth, gt_depth, gt_contact)` returns plain counts
that add up over readings (a run, a finger, a data set); `summarise` turns a sum of them
into figures:

- contact IoU = |predicted contact AND true contact| / |predicted contact OR true
  contact|, in pixels, summed over the readings before dividing (so a large touch weighs
  more than a small one). Predicted contact = pixels with `pred_depth > 0`. None when
  neither ever has contact.
- depth MAE (mm) = the mean over true contact pixels of |predicted - true| depth along the
  sensor's +z. Where the prediction has no contact, its depth counts as the gel surface
  (GEL_DISTANCE_M: an unpressed gel), so a missed pixel costs exactly the press it
  missed. None when there is no true contact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M


@dataclass
class DepthCounts:
    """Pixel counts and the summed depth error of one or more readings."""

    intersection: int = 0
    union: int = 0
    abs_error_mm_sum: float = 0.0
    error_count: int = 0  # true contact pixels

    def __add__(self, other: DepthCounts) -> DepthCounts:
        return DepthCounts(
            self.intersection + other.intersection,
            self.union + other.union,
            self.abs_error_mm_sum + other.abs_error_mm_sum,
            self.error_count + other.error_count,
        )


def depth_counts(
    pred_depth: np.ndarray, gt_depth: np.ndarray, gt_contact: np.ndarray | None = None
) -> DepthCounts:
    """Counts for one reading; depths (H, W) in metres, 0 off-contact. `gt_contact`
    defaults to `gt_depth > 0` (the simulator's contact mask is exactly that)."""
    if pred_depth.shape != gt_depth.shape:
        raise ValueError(f"pred_depth {pred_depth.shape} and gt_depth {gt_depth.shape} differ")
    truth = gt_depth > 0 if gt_contact is None else np.asarray(gt_contact, bool)
    if truth.shape != gt_depth.shape:
        raise ValueError(f"gt_contact {truth.shape} and gt_depth {gt_depth.shape} differ")
    pred = pred_depth > 0
    surface = np.where(pred, pred_depth, GEL_DISTANCE_M)[truth].astype(np.float64)
    error_mm = np.abs(surface - gt_depth[truth].astype(np.float64)) * 1000.0
    return DepthCounts(
        intersection=int((pred & truth).sum()),
        union=int((pred | truth).sum()),
        abs_error_mm_sum=float(error_mm.sum()),
        error_count=int(truth.sum()),
    )


def summarise(counts: DepthCounts) -> dict:
    """{"contact_iou", "depth_mae_mm", "contact_px", "union_px"} of summed counts."""
    return {
        "contact_iou": counts.intersection / counts.union if counts.union else None,
        "depth_mae_mm": counts.abs_error_mm_sum / counts.error_count
        if counts.error_count
        else None,
        "contact_px": counts.error_count,
        "union_px": counts.union,
    }
