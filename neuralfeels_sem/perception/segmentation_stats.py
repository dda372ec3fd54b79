"""Running figures of camera segmentation over a run: mask IoU, frames with no object, cost."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.perception.camera_segmentation import Segmentation


def mask_iou(mask: np.ndarray, reference: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1.0 when both are empty)."""
    if mask.shape != reference.shape:
        raise ValueError(f"mask shape {mask.shape} does not match reference {reference.shape}")
    union = np.logical_or(mask, reference).sum()
    return 1.0 if union == 0 else float(np.logical_and(mask, reference).sum() / union)


@dataclass
class SegmentationStats:
    """Sums over the segmented camera frames; `last_iou` is the latest frame's (None: no GT)."""

    frames: int = 0
    skipped_no_object: int = 0
    iou_sum: float = 0.0
    iou_frames: int = 0
    seconds_sum: float = 0.0
    last_iou: float | None = None

    def add(self, result: Segmentation, depth: np.ndarray, gt_mask: np.ndarray | None) -> None:
        """Count one frame; with a ground-truth mask (sim), score against its valid-depth pixels.

        A mask from depth cannot hold pixels without depth, so the reference is the ground
        truth where depth is valid (noise models drop pixels at edges and grazing angles).
        """
        self.frames += 1
        self.skipped_no_object += not result.found
        self.seconds_sum += result.seconds
        self.last_iou = None
        if gt_mask is not None:
            valid = np.isfinite(depth) & (depth > 0)
            self.last_iou = mask_iou(result.mask, gt_mask.astype(bool) & valid)
            self.iou_sum += self.last_iou
            self.iou_frames += 1

    def summary(self) -> dict:
        """Figures for metrics.json: frames, skipped ones, mean IoU (None without GT), mean ms."""
        return {
            "camera_frames_segmented": self.frames,
            "camera_frames_no_object": self.skipped_no_object,
            "mask_iou_mean": self.iou_sum / self.iou_frames if self.iou_frames else None,
            "segmentation_ms_mean": 1000.0 * self.seconds_sum / self.frames
            if self.frames
            else None,
        }
