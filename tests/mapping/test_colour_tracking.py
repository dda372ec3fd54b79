"""Colour consistency with earlier views (mapping.tracker.colour): it sees a turn the SDF
cannot (a painted sphere's spin), its Jacobian matches finite differences, keyframes pull
accumulated drift back when the object returns to an orientation seen before, and its
settings are range-checked."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.mapping.colour_keyframes import ColourConfig, ColourKeyframes, turned_deg
from neuralfeels_sem.mapping.colour_views import colour_features, pixels_of
from neuralfeels_sem.mapping.pose_error import PoseErrorLog
from neuralfeels_sem.mapping.pose_source import TrackedPose
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig, se3_exp
from neuralfeels_sem.mapping.residual_terms import ResidualTerm, stack_terms
from tests.mapping.colour_scene import (
    RADIUS,
    SphereMapper,
    frame_of,
    render,
    sphere_sdf,
    surface_samples,
    turning,
)


def sphere_source(**colour) -> TrackedPose:
    config = TrackerConfig(rotation_scale=RADIUS, colour=ColourConfig(**colour))
    source = TrackedPose("track", None, PoseTracker(config))
    source.errors = PoseErrorLog(surface_samples)  # no mesh: the sphere's surface
    return source


def camera_world(frame) -> np.ndarray:
    return SphereMapper().frame_points(frame, np.eye(4))["camera"]


def track(source: TrackedPose, poses: list[np.ndarray]) -> np.ndarray:
    mapper = SphereMapper()
    for k, gt in enumerate(poses):
        est = source.estimate(frame_of(k, gt), mapper)
    return est


def test_colour_recovers_a_spin_the_shape_cannot_show() -> None:
    """A painted sphere turning 3 degrees a frame: its SDF sees no turn at all."""
    poses = turning(10, 3.0)
    blind = track(sphere_source(weight=0.0), poses)
    assert turned_deg(blind, poses[-1]) > 20.0  # no motion seen: the prior's guess stays
    source = sphere_source()
    seen = track(source, poses)
    assert turned_deg(seen, poses[-1]) < 1.0
    np.testing.assert_allclose(seen[:3, 3], poses[-1][:3, 3], atol=5e-4)
    m = source.metrics()
    assert m["pose_frames_tracked"] == 9 and m["pose_frames_degenerate"] == 0
    assert m["pose_frames_without_colour"] == 0 and m["pose_colour_keyframes"] >= 2
    assert m["pose_error_mm"] < 1.0


def test_colour_residual_gradient_matches_finite_differences() -> None:
    """The colour rows' Jacobian comes from autograd through the bilinear lookup."""
    poses = turning(2, 3.0)
    keyframes = ColourKeyframes(ColourConfig(blur_px=2.0))
    first = frame_of(0, poses[0])
    keyframes.add(keyframes.view(first, camera_world(first)), poses[0], True)
    now = frame_of(1, poses[1])
    view = keyframes.view(now, camera_world(now))
    (term,) = keyframes.terms(view, poses[1])
    rows = term.residuals
    obj_T_world = invert_pose(poses[1])
    q = term.points_world @ obj_T_world[:3, :3].T + obj_T_world[:3, 3]
    full = torch.as_tensor(q, dtype=torch.float32)
    x = full.clone().requires_grad_(True)
    (grad,) = torch.autograd.grad(rows(x).sum(), x)
    eps = 2e-5
    for axis in range(3):
        step = torch.zeros(3)
        step[axis] = eps
        numeric = (rows(full + step) - rows(full - step)) / (2 * eps)
        strong = grad[:, axis].abs() > 0.2 * grad[:, axis].abs().max()
        np.testing.assert_allclose(numeric[strong], grad[strong, axis], rtol=0.15, atol=0.05)


def test_keyframes_pull_drift_back_on_return() -> None:
    """Out 8 frames and back: drift injected at the turn is pulled back once the object
    faces the keyframes it showed on the way out (a loop closure); with keyframes off,
    only the previous frame is compared and the drift stays."""
    out = turning(9, 3.0)
    back = [out[8 - k] for k in range(1, 9)]
    errors = {}
    for refs in (0, 1):
        source = sphere_source(keyframe_refs=refs, keyframe_angle_deg=5.0)
        mapper = SphereMapper()
        for k, gt in enumerate(out):
            source.estimate(frame_of(k, gt), mapper)
        drift = se3_exp(np.array([0, 0, 0, 0, 0, np.deg2rad(2.0)]))
        drift[:3, 3] = 0.0
        off = out[8] @ drift
        source.history = [out[7] @ drift, off]  # as if the turn had drifted by 2 degrees
        source.colour.previous.world_T_object = off
        for k, gt in enumerate(back, start=9):
            est = source.estimate(frame_of(k, gt), mapper)
        errors[refs] = turned_deg(est, back[-1])
    assert errors[0] > 1.5
    assert errors[1] < 0.5


def test_resume_restores_the_colour_views(tmp_path) -> None:
    """A source resumed from its state (through a weights-only checkpoint file) keeps its
    keyframes and previous view, and continues exactly as one that never stopped."""
    poses = turning(8, 3.0)
    straight = sphere_source(keyframe_angle_deg=5.0)
    last = track(straight, poses)
    first = sphere_source(keyframe_angle_deg=5.0)
    track(first, poses[:4])
    torch.save(first.state(), tmp_path / "pose.pt")
    resumed = sphere_source(keyframe_angle_deg=5.0)
    resumed.load_state(torch.load(tmp_path / "pose.pt", weights_only=True))
    assert [k.index for k in resumed.colour.keyframes] == [k.index for k in first.colour.keyframes]
    assert resumed.colour.previous.index == 3
    mapper = SphereMapper()
    for k, gt in enumerate(poses[4:], start=4):
        again = resumed.estimate(frame_of(k, gt), mapper)
    np.testing.assert_array_equal(again, last)
    assert resumed.metrics()["pose_colour_keyframes"] == straight.metrics()["pose_colour_keyframes"]


def test_features_pixels_and_keyframe_choice() -> None:
    reading = render(turning(1, 0.0)[0])
    feats = colour_features(reading.rgb, blur_px=0.0)
    assert feats.shape == (*reading.rgb.shape[:2], 2)
    rgb = reading.rgb.astype(float)
    total = rgb.sum(axis=2)
    bright = total > 100
    np.testing.assert_allclose(feats[bright][:, 0], (rgb[..., 0] / total)[bright], atol=1e-5)
    mapper = SphereMapper()
    frame = frame_of(0, turning(1, 0.0)[0])
    world = mapper.frame_points(frame, np.eye(4))["camera"]
    rows, cols = pixels_of(reading, world)
    assert reading.mask[rows, cols].all() and len(set(zip(rows, cols))) == len(world)

    keyframes = ColourKeyframes(ColourConfig(keyframe_angle_deg=10.0, keyframe_max_angle_deg=20.0))
    poses = turning(16, 2.0)  # keyframes every 10+ degrees: frames 0, 6, 12
    for k, gt in enumerate(poses):
        f = frame_of(k, gt)
        keyframes.add(keyframes.view(f, camera_world(f)), gt, True)
    assert [v.index for v in keyframes.keyframes] == [0, 6, 12]
    refs = keyframes.references(poses[1])
    assert [r.index for r in refs] == [15, 0]  # the previous frame, then the nearest keyframe
    assert keyframes.add(None, np.eye(4), True) is None  # no view (no camera): nothing kept


def test_a_kept_prediction_never_becomes_a_keyframe() -> None:
    keyframes = ColourKeyframes(ColourConfig(keyframe_angle_deg=1.0))
    for k, gt in enumerate(turning(3, 5.0)):
        f = frame_of(k, gt)
        keyframes.add(keyframes.view(f, camera_world(f)), gt, k == 0)
    assert [v.index for v in keyframes.keyframes] == [0] and keyframes.previous.index == 2


def test_stacked_terms_weigh_each_term_against_the_sdf() -> None:
    pts = torch.zeros((10, 3), dtype=torch.float64)
    weights = torch.full((10,), 2.0, dtype=torch.float64)
    term = ResidualTerm(np.ones((4, 3)), lambda x: x[:, 0] * 0 + 1.0, weight=3.0)
    fn, all_pts, all_w = stack_terms(sphere_sdf, pts, weights, [term])
    assert len(all_pts) == 14 and float(all_w[10:].sum()) == pytest.approx(3.0 * 20.0)
    out = fn(all_pts.to(torch.float32))
    np.testing.assert_allclose(out[:10].numpy(), -RADIUS, rtol=1e-6)
    np.testing.assert_allclose(out[10:].numpy(), 1.0)
    with pytest.raises(ValueError, match="shape"):
        ResidualTerm(np.ones((4, 2)), sphere_sdf, 1.0)


@pytest.mark.parametrize(
    "bad",
    [
        {"weight": -1.0},
        {"scale_m": 0.0},
        {"max_depth_gap_m": 0.0},
        {"keyframe_angle_deg": 0.0},
        {"min_pixels": 0},
        {"min_pixels": 2000, "max_pixels": 1000},
        {"keyframe_refs": -1},
    ],
)
def test_colour_settings_are_range_checked(bad) -> None:
    with pytest.raises(ValueError, match="mapping.tracker.colour"):
        ColourConfig(**bad)
