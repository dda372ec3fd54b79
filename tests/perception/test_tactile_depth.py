"""Tactile contact depth: simulator pass-through and the image-difference estimate."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig
from tests.mapping.synthetic import digit_reading, object_pose

H, W = DIGIT_INTRINSICS.height, DIGIT_INTRINSICS.width


def pressed_image(
    background: np.ndarray, centre: tuple[int, int], radius: int, peak: float
) -> tuple[np.ndarray, np.ndarray]:
    """Background brightened inside a disk by a cone profile peaking at `peak` grey levels."""
    v, u = np.mgrid[0:H, 0:W]
    r = np.hypot(u - centre[0], v - centre[1])
    change = np.clip(peak * (1.0 - r / radius) + 25.0, 0.0, None) * (r < radius)
    image = np.clip(background.astype(np.float32) + change[..., None], 0, 255).astype(np.uint8)
    return image, r < radius


@pytest.fixture()
def background() -> np.ndarray:
    rng = np.random.default_rng(0)
    base = np.linspace(60, 140, W)[None, :, None] + np.zeros((H, 1, 3))
    return np.clip(base + rng.normal(0, 2.0, (H, W, 3)), 0, 255).astype(np.uint8)


def test_gt_source_returns_simulator_depth() -> None:
    reading = digit_reading("index", object_pose(), np.array([0.0, 1.0, 0.0]))
    depth = TactileDepth(TactileDepthConfig("gt"))(reading)
    np.testing.assert_array_equal(depth, reading.gt_depth)
    assert depth.dtype == np.float32 and depth.any()


def test_gt_source_without_ground_truth_is_a_data_error() -> None:
    reading = digit_reading("index", object_pose(), np.array([0.0, 1.0, 0.0]))
    reading.gt_depth = None
    with pytest.raises(DataError, match="source=image"):
        TactileDepth(TactileDepthConfig("gt"))(reading)


def test_unknown_source_is_refused_by_the_config() -> None:
    with pytest.raises(ValueError, match="lidar"):
        TactileDepthConfig("lidar")


def test_image_estimate_finds_the_pressed_disk(background: np.ndarray) -> None:
    image, disk = pressed_image(background, (120, 160), 40, peak=60.0)
    reading = TactileReading("middle", image, np.eye(4), DIGIT_INTRINSICS, background=background)
    depth = TactileDepth(TactileDepthConfig("image"))(reading)
    mask = depth > 0
    iou = (mask & disk).sum() / (mask | disk).sum()
    assert iou > 0.85
    assert depth[mask].min() >= GEL_DISTANCE_M - MAX_PENETRATION_M - 1e-7
    assert depth[mask].max() <= GEL_DISTANCE_M + 1e-7
    # Deeper at the centre of the press (bigger change) than near its rim.
    assert depth[160, 120] < depth[160, 120 + 30]
    assert depth[160, 120] == pytest.approx(GEL_DISTANCE_M - MAX_PENETRATION_M, abs=2e-4)


def test_image_estimate_without_contact_is_empty(background: np.ndarray) -> None:
    rng = np.random.default_rng(1)
    noisy = np.clip(background + rng.normal(0, 3.0, background.shape), 0, 255).astype(np.uint8)
    reading = TactileReading("ring", noisy, np.eye(4), DIGIT_INTRINSICS, background=background)
    assert not TactileDepth(TactileDepthConfig("image"))(reading).any()


def test_tiny_blob_is_not_a_contact(background: np.ndarray) -> None:
    image, _ = pressed_image(background, (60, 60), 6, peak=80.0)
    reading = TactileReading("thumb", image, np.eye(4), DIGIT_INTRINSICS, background=background)
    assert not TactileDepth(TactileDepthConfig("image", min_contact_px=150))(reading).any()


def test_image_source_needs_a_background(background: np.ndarray) -> None:
    reading = TactileReading("index", background, np.eye(4), DIGIT_INTRINSICS, background=None)
    with pytest.raises(DataError, match="background"):
        TactileDepth(TactileDepthConfig("image"))(reading)


def test_real_digit_frames(shared_data) -> None:
    """Real frames: a background against itself (plus sensor noise) shows no contact; a grasp
    frame against a background of the same rig shows a bounded contact region."""
    folder = shared_data / "digit_real"
    bg = cv2.imread(str(folder / "backgrounds" / "aurova_bg_1.png"))[..., ::-1].copy()
    grasp = cv2.imread(str(folder / "contact" / "ycb_grasp_1.png"))[..., ::-1].copy()
    estimator = TactileDepth(
        TactileDepthConfig("image", contact_threshold=20.0, full_press_intensity=80.0)
    )
    noisy = np.clip(bg + np.random.default_rng(0).normal(0, 2.0, bg.shape), 0, 255).astype(np.uint8)
    assert not estimator.from_image(noisy, bg).any()
    depth = estimator.from_image(grasp, bg)
    share = (depth > 0).mean()
    assert 0.01 < share < 0.6
