"""The segmentation overlay: tint where segmented, red outline where the ground truth is."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.viz.segmentation_overlay import (
    GT_OUTLINE,
    save_segmentation_overlay,
    segmentation_overlay,
)
from tests.viz.images import assert_png


def _reading(with_gt: bool) -> CameraReading:
    gt = np.zeros((120, 160), bool)
    gt[40:80, 50:110] = True
    rgb = np.full((120, 160, 3), 90, np.uint8)
    depth = np.full((120, 160), 0.4, np.float32)
    return CameraReading(
        rgb=rgb,
        depth=depth,
        intrinsics=Intrinsics.from_fov(160, 120, 50.0),
        world_T_camera=np.eye(4),
        mask=gt if with_gt else None,
    )


def test_tint_inside_the_mask_and_outline_of_the_truth(tmp_path) -> None:
    reading = _reading(with_gt=True)
    mask = np.zeros((120, 160), bool)
    mask[60:100, 20:60] = True
    picture = segmentation_overlay(reading, mask, scale=2)
    assert picture.shape == (240, 320, 3)
    assert picture[160, 80, 1] > 140 > picture[10, 10, 1]  # tinted green / untouched grey
    red = np.all(picture == GT_OUTLINE, axis=-1)
    assert red[80:82, 100:220].any() and not red[120:140, 140:180].any()  # outline, not fill
    pixels = assert_png(save_segmentation_overlay(reading, mask, tmp_path / "seg.png"))
    np.testing.assert_array_equal(pixels, picture)


def test_no_outline_without_ground_truth() -> None:
    picture = segmentation_overlay(_reading(with_gt=False), np.zeros((120, 160), bool))
    assert not np.all(picture == GT_OUTLINE, axis=-1).any()


def test_a_mask_of_another_size_is_refused() -> None:
    with pytest.raises(ValueError, match="mask shape"):
        segmentation_overlay(_reading(with_gt=True), np.zeros((10, 10), bool))
