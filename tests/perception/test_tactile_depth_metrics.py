"""Contact IoU and depth error counts of tactile depth against ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.perception.tactile_depth_metrics import DepthCounts, depth_counts, summarise


def test_counts_of_one_reading_by_hand() -> None:
    gt = np.zeros((4, 4), np.float32)
    gt[0, :3] = GEL_DISTANCE_M - 0.001  # 3 px pressed 1 mm
    pred = np.zeros((4, 4), np.float32)
    pred[0, 1:4] = GEL_DISTANCE_M - 0.0015  # 2 px overlap, 1 extra, 1 missed
    counts = depth_counts(pred, gt)
    assert (counts.intersection, counts.union, counts.error_count) == (2, 4, 3)
    # Overlap: 0.5 mm each; the missed pixel counts as the unpressed gel: 1 mm.
    assert counts.abs_error_mm_sum == pytest.approx(0.5 + 0.5 + 1.0)
    figures = summarise(counts)
    assert figures["contact_iou"] == pytest.approx(0.5)
    assert figures["depth_mae_mm"] == pytest.approx(2.0 / 3.0)


def test_an_explicit_mask_overrides_depth_and_sums_add_up() -> None:
    gt = np.full((2, 2), GEL_DISTANCE_M - 0.002, np.float32)
    mask = np.array([[True, False], [False, False]])
    counts = depth_counts(gt.copy(), gt, mask)
    assert (counts.intersection, counts.union, counts.error_count) == (1, 4, 1)
    total = counts + counts
    assert total == DepthCounts(2, 8, 0.0, 2)


def test_no_contact_anywhere_has_no_figures() -> None:
    empty = np.zeros((3, 3), np.float32)
    figures = summarise(depth_counts(empty, empty))
    assert figures["contact_iou"] is None and figures["depth_mae_mm"] is None


def test_shapes_must_match() -> None:
    with pytest.raises(ValueError, match="differ"):
        depth_counts(np.zeros((2, 2)), np.zeros((3, 3)))
