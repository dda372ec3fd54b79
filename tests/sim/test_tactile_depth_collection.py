"""Training renders of the tactile depth network: shading change + ground truth, repeatable."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.sim.backgrounds import procedural_background
from neuralfeels_sem.sim.digit_poses import pose_pressing
from neuralfeels_sem.sim.tactile_depth_collection import (
    DepthPressSettings,
    depth_backgrounds,
    render_depth_samples,
)
from neuralfeels_sem.sim.tactile_renderer import DigitRenderer
from neuralfeels_sem.sim.touch_sources import primitive_objects

SETTINGS = DepthPressSettings(
    sensors=["index", "thumb"],
    library_objects=[],
    firmness_mm={"index": 1.5, "thumb": 0.7},
    firmness_spread=0.35,
    uniform_press_fraction=0.5,
    min_press_mm=0.1,
    miss_fraction=0.0,
    max_gap_mm=1.0,
    max_tilt_deg=10.0,
    edge_press_fraction=0.0,
    edge_tilt_deg=[15.0, 40.0],
    texture_scale=1.0,
)


def test_a_render_is_its_background_plus_its_change() -> None:
    sphere = primitive_objects(["wood"])[1]
    background = procedural_background(5)
    renderer = DigitRenderer(sphere, background=background, noise_std=0.0, seed=3)
    pose = pose_pressing(np.array([0.0, 0.0, 0.045]), np.array([0.0, 0.0, 1.0]), 0.001)
    try:
        render = renderer.render(np.eye(4), pose)
        change, truth = renderer.render_change(np.eye(4), pose)
    finally:
        renderer.close()
    composed = np.clip(background.astype(np.float32) + change, 0, 255).astype(np.uint8)
    np.testing.assert_array_equal(composed, render.image)
    np.testing.assert_array_equal(truth.depth, render.depth)
    assert np.abs(change).max() > 20 and render.contact_mask.sum() > 1000


def test_samples_hold_contact_ground_truth_and_repeat_from_the_seed() -> None:
    a = render_depth_samples(4, ["plastic", "fabric"], SETTINGS, seed=3)
    b = render_depth_samples(4, ["plastic", "fabric"], SETTINGS, seed=3)
    np.testing.assert_array_equal(a.change, b.change)
    np.testing.assert_array_equal(a.press_mm, b.press_mm)
    assert a.finger == ["index", "thumb", "index", "thumb"]
    assert a.contact.any(axis=(1, 2)).all()  # every press reaches the gel (no misses)
    press = a.press_mm[a.contact].astype(np.float32)
    assert press.min() > 0 and press.max() < 2.5
    depth = a.gt_depth(0)
    assert np.allclose(
        depth[a.contact[0]],
        GEL_DISTANCE_M - a.press_mm[0][a.contact[0]].astype(np.float32) / 1000,
        atol=1e-6,
    )
    assert sum(a.objects.values()) == 4


def test_real_backgrounds_split_between_training_and_held_out(tmp_path: Path) -> None:
    for i in range(6):
        cv2.imwrite(str(tmp_path / f"bg_{i}.png"), np.full((320, 240, 3), 10 * i, np.uint8))
    train, train_names = depth_backgrounds([0, 1], tmp_path, (1, 3))
    held, held_names = depth_backgrounds([100], tmp_path, (0, 3))
    assert train.shape == (6, 320, 240, 3) and held.shape == (3, 320, 240, 3)
    assert held_names == ["procedural:100", "real:bg_0.png", "real:bg_3.png"]
    assert not set(train_names) & set(held_names)
    only_procedural, _ = depth_backgrounds([0], tmp_path / "absent", (1, 3))
    assert len(only_procedural) == 1
