"""Pose tracking against an SDF: Lie-group helpers, the LM tracker on an analytic
sphere-and-box shape, the ground-truth-mesh grid SDF, and an end-to-end tracked run."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest
import torch
import trimesh

from neuralfeels_sem.core.geometry import invert_pose, transform_points
from neuralfeels_sem.mapping.known_shape import GridSdf, mesh_sdf_grid
from neuralfeels_sem.mapping.pose_tracker import (
    PoseTracker,
    TrackerConfig,
    constant_velocity,
    robust_weights,
    se3_exp,
    se3_log,
)
from tests.helpers import run_cli

SPHERE_R = 0.03
BOX_CENTRE = torch.tensor([0.03, 0.0, 0.01], dtype=torch.float64)
BOX_HALF = torch.tensor([0.02, 0.012, 0.008], dtype=torch.float64)


def sphere_box_sdf(x: torch.Tensor) -> torch.Tensor:
    """Exact SDF of a sphere at the origin united with an off-centre box (no symmetry)."""
    x = x.to(torch.float64)
    sphere = x.norm(dim=1) - SPHERE_R
    d = (x - BOX_CENTRE).abs() - BOX_HALF
    box = d.clamp_min(0).norm(dim=1) + d.max(dim=1).values.clamp_max(0)
    return torch.minimum(sphere, box)


def surface_points(count: int, seed: int = 0) -> np.ndarray:
    """Points on the sphere-and-box surface: random points projected along the gradient."""
    rng = np.random.default_rng(seed)
    x = torch.as_tensor(rng.uniform(-0.05, 0.06, (4 * count, 3)))
    for _ in range(30):
        x = x.detach().requires_grad_(True)
        d = sphere_box_sdf(x)
        (g,) = torch.autograd.grad(d.sum(), x)
        x = x - d[:, None] * g / g.norm(dim=1, keepdim=True).clamp_min(1e-9)
    x = x.detach()
    on = sphere_box_sdf(x).abs() < 1e-6
    return x[on][:count].numpy()


def pose(rotvec_deg: tuple[float, float, float], t: tuple[float, float, float]) -> np.ndarray:
    xi = np.concatenate([np.zeros(3), np.deg2rad(rotvec_deg)])
    out = se3_exp(xi)
    out[:3, 3] = t
    return out


def error_mm(a: np.ndarray, b: np.ndarray, pts: np.ndarray) -> float:
    return 1e3 * float(
        np.linalg.norm(transform_points(a, pts) - transform_points(b, pts), axis=1).mean()
    )


# ------------------------------------------------------------------ Lie helpers
def test_se3_exp_log_round_trip() -> None:
    rng = np.random.default_rng(1)
    for scale in (1e-10, 1e-3, 0.5, 2.5):
        xi = rng.normal(size=6) * scale
        xi[3:] *= min(1.0, 3.0 / max(np.linalg.norm(xi[3:]), 1e-12))  # angle below pi
        t = se3_exp(xi)
        np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(se3_log(t), xi, atol=1e-9)
    with pytest.raises(ValueError):
        se3_exp(np.zeros(5))


def test_constant_velocity_repeats_the_last_motion() -> None:
    a = pose((0, 0, 0), (0.0, 0.0, 0.1))
    b = pose((0, 0, 3), (0.001, 0.0, 0.1))
    c = constant_velocity([a, b])
    np.testing.assert_allclose(c, b @ invert_pose(a) @ b, atol=1e-12)  # a = I rotation
    np.testing.assert_allclose(constant_velocity([b]), b)


def test_robust_weights() -> None:
    r = torch.tensor([0.0, 0.001, 0.004, -0.01])
    w, rho = robust_weights(r, "huber", 0.002)
    assert torch.allclose(w, torch.tensor([1.0, 1.0, 0.5, 0.2]))
    w, rho = robust_weights(r, "cauchy", 0.002)
    assert w[0] == 1 and (w[1:].diff() < 0).all() and (rho >= 0).all()
    with pytest.raises(ValueError):
        robust_weights(r, "l1", 0.002)


# ------------------------------------------------------------------ the tracker
def test_tracks_a_sphere_and_box_through_a_trajectory() -> None:
    """Every frame starts from the constant-velocity prediction; error stays below 1 mm."""
    obj_pts = surface_points(1500)
    # Only the half facing the "camera" (+x) is observed, with 0.3 mm of noise.
    rng = np.random.default_rng(2)
    tracker = PoseTracker(TrackerConfig(robust_loss="huber", prior_weight=1e-3))
    truth = [pose((0, 0, 0), (0.0, 0.0, 0.15))]
    for k in range(1, 15):  # wobble plus a steady turn: ~3 deg and ~1.5 mm per frame
        truth.append(
            pose(
                (3 * np.sin(0.5 * k), 1.5 * np.cos(0.3 * k), 3.0 * k),
                (0.0015 * k, 0.001 * np.sin(k), 0.15),
            )
        )
    estimates = [truth[0]]
    errors = []
    for k in range(1, len(truth)):
        world = transform_points(truth[k], obj_pts)
        visible = world[:, 0] > truth[k][0, 3] - 0.005
        seen = world[visible] + rng.normal(scale=3e-4, size=(int(visible.sum()), 3))
        predicted = constant_velocity(estimates[-2:])
        est, info = tracker.track(
            {"camera": torch.as_tensor(seen)}, sphere_box_sdf, predicted, prior=predicted
        )
        assert info["skipped"] is None and info["final_rms_mm"] < info["initial_rms_mm"]
        estimates.append(est)
        errors.append(error_mm(est, truth[k], obj_pts))
    assert max(errors) < 1.0, errors
    # Without tracking, the prediction alone drifts far beyond that.
    assert error_mm(constant_velocity([truth[0]]), truth[-1], obj_pts) > 10


def test_recovers_a_large_initial_offset_from_touch_and_camera() -> None:
    obj_pts = surface_points(1200, seed=3)
    truth = pose((5, -4, 8), (0.01, -0.005, 0.2))
    init = truth @ pose((-4, 3, -5), (0.004, 0.003, -0.003))
    world = transform_points(truth, obj_pts)
    points = {"camera": world[:800], "index": world[800:900], "thumb": world[900:1000]}
    both = {"camera": 1.0, "tactile": 1.0}  # touch is off by default
    est, info = PoseTracker(TrackerConfig(iterations=30, source_weights=both)).track(
        points, sphere_box_sdf, init
    )
    assert info["points"] == 1000
    assert error_mm(init, truth, obj_pts) > 5
    assert error_mm(est, truth, obj_pts) < 0.5, info


def test_source_weights_switch_modalities_off() -> None:
    obj_pts = surface_points(600, seed=4)
    truth = pose((0, 0, 0), (0.0, 0.0, 0.1))
    init = truth @ pose((0, 0, 3), (0.002, 0, 0))
    world = transform_points(truth, obj_pts)
    bad_camera = world[:400] + np.array([0.0, 0.0, 0.01])  # a camera 1 cm off
    points = {"camera": bad_camera, "index": world[400:]}
    touch_only = PoseTracker(TrackerConfig(source_weights={"camera": 0.0}, iterations=30))
    est, info = touch_only.track(points, sphere_box_sdf, init)
    assert info["points"] == 200
    assert error_mm(est, truth, obj_pts) < 0.5


def test_too_few_points_keeps_the_prediction_and_says_so(caplog) -> None:
    tracker = PoseTracker(TrackerConfig(min_points=50))
    init = pose((0, 0, 10), (0.0, 0.0, 0.1))
    predicted = pose((0, 0, 12), (0.001, 0.0, 0.1))
    few = {"camera": surface_points(20)}
    with caplog.at_level(logging.DEBUG):  # the pose source warns about kept frames
        est, info = tracker.track(few, sphere_box_sdf, init, prior=predicted)
    np.testing.assert_array_equal(est, predicted)
    assert info["skipped"] == "too few points (20 < 50)"
    assert "too few points (20 < 50)" in caplog.text
    est, info = tracker.track({}, sphere_box_sdf, init)
    np.testing.assert_array_equal(est, init)
    assert info["points"] == 0 and info["skipped"]


def test_prior_holds_unobservable_directions() -> None:
    """A sphere's spin cannot be seen; the prior keeps it at the prediction."""
    rng = np.random.default_rng(5)
    dirs = rng.normal(size=(500, 3))
    pts = SPHERE_R * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    truth = pose((0, 0, 0), (0.0, 0.0, 0.1))
    predicted = truth @ pose((0, 0, 20), (0.002, 0.0, 0.0))

    def sphere(x: torch.Tensor) -> torch.Tensor:
        return x.norm(dim=1) - SPHERE_R

    est, _ = PoseTracker(TrackerConfig(iterations=30)).track(
        {"camera": transform_points(truth, pts)}, sphere, predicted, prior=predicted
    )
    np.testing.assert_allclose(est[:3, 3], truth[:3, 3], atol=1e-4)  # translation observed
    np.testing.assert_allclose(est[:3, :3], predicted[:3, :3], atol=1e-3)  # spin from the prior


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="iterations"):
        TrackerConfig(iterations=0)
    with pytest.raises(ValueError, match="robust_loss"):
        TrackerConfig(robust_loss="l2")
    with pytest.raises(ValueError, match="source_weights"):
        TrackerConfig(source_weights={"camera": -1.0})
    with pytest.raises(ValueError, match="shape"):
        PoseTracker().track({"camera": np.zeros((10, 2))}, sphere_box_sdf, np.eye(4))
    with pytest.raises(ValueError, match="4x4"):
        PoseTracker().track({}, sphere_box_sdf, np.eye(3))


# ------------------------------------------------------------------ known shape
def test_grid_sdf_of_a_mesh_matches_the_analytic_distance() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=SPHERE_R)
    sdf = GridSdf(*mesh_sdf_grid(mesh, resolution=48, use_disk=False))
    rng = np.random.default_rng(6)
    x = rng.uniform(-0.045, 0.045, (4000, 3))
    true = np.linalg.norm(x, axis=1) - SPHERE_R
    got = sdf(torch.as_tensor(x)).numpy()
    near = np.abs(true) < 0.003
    # The icosphere's flat faces sit up to ~0.1 mm inside the true sphere.
    assert np.abs(got - true)[near].mean() < 2e-4
    assert np.all(np.sign(got[np.abs(true) > 0.003]) == np.sign(true[np.abs(true) > 0.003]))
    far = torch.tensor([[0.2, 0.0, 0.0]])  # outside the grid: still a distance
    assert abs(float(sdf(far)) - (0.2 - SPHERE_R)) < 2e-3
    x_t = torch.as_tensor(x[near][:50], dtype=torch.float32).requires_grad_(True)
    (g,) = torch.autograd.grad(sdf(x_t).sum(), x_t)
    radial = x_t.detach() / x_t.detach().norm(dim=1, keepdim=True)
    assert float((g * radial).sum(dim=1).min()) > 0.9  # the gradient points outward


def test_grid_sdf_is_cached_in_memory() -> None:
    mesh = trimesh.creation.box(extents=(0.04, 0.03, 0.02))
    a = mesh_sdf_grid(mesh, resolution=24, use_disk=False)
    b = mesh_sdf_grid(mesh, resolution=24, use_disk=False)
    assert a is b
    with pytest.raises(ValueError):
        GridSdf(np.zeros((4, 4)), np.zeros(3), 0.01)


# ------------------------------------------------------------------ end to end
@pytest.mark.slow
def test_cli_run_with_known_shape_tracking_reports_the_pose_error(tmp_path) -> None:
    """A short simulated run: metrics.json carries the pose error, pose_error.png exists."""
    result = run_cli(
        [
            "object=patched_toy",
            "classifier=oracle",
            "mapping.pose=track_known_shape",
            "sensor.duration_s=0.5",
            "mapping.mapper.warmup_steps=10",
            "eval.every_k_frames=10",
            "eval.num_surface_samples=2000",
            "eval.image_views=1",
            "eval.image_size=48",
            "eval.shape_samples=2000",
            "eval.mesh_resolution=48",
            "viz.progression_snapshots=1",
            f"hydra.run.dir={tmp_path}",
        ],
        timeout=1800,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["pose_source"] == "track_known_shape"
    assert metrics["pose_frames_tracked"] == metrics["frames"] - 1
    assert len(metrics["pose_error_curve"]) == metrics["frames"]
    assert 0.0 <= metrics["pose_error_mm"] < 2.3
    assert (tmp_path / "pose_error.png").stat().st_size > 0


def test_runaway_steps_are_damped_and_a_diverged_result_keeps_the_prediction(caplog) -> None:
    """Far from the surface a clamped field is flat; the tracker must not jump off to infinity."""

    def plane_with_flat_far_field(x: torch.Tensor) -> torch.Tensor:
        return x[:, 0].clamp(-0.5, 0.5)  # a wall at x = 0, constant beyond +-0.5 m

    world = np.random.default_rng(0).uniform(-0.05, 0.05, (300, 3))
    world[:, 0] = 0.2  # every point 20 cm in front of the wall
    init = np.eye(4)
    # Every LM step is capped at 1 cm, so 10 steps move the object at most 10 cm (and
    # leave it off the wall, sliding freely along it: the fit checks are off here).
    no_fit_check = TrackerConfig(
        iterations=10,
        prior_weight=0.0,
        max_motion_m=1.0,
        min_inlier_share=0.0,
        min_conditioning=0.0,
    )
    est, info = PoseTracker(no_fit_check).track({"camera": world}, plane_with_flat_far_field, init)
    assert info["skipped"] is None
    assert 0.005 < np.linalg.norm(est[:3, 3]) <= 0.1 + 1e-9
    # A result further than max_motion_m from the prediction is not trusted.
    with caplog.at_level(logging.DEBUG):
        est, info = PoseTracker(
            TrackerConfig(iterations=10, prior_weight=0.0, max_motion_m=0.005)
        ).track({"camera": world}, plane_with_flat_far_field, init)
    assert info["skipped"].startswith("diverged")
    np.testing.assert_array_equal(est, init)
    assert "diverged" in caplog.text


def test_repeated_constant_velocity_stays_a_rigid_transform() -> None:
    """Extrapolating from slightly non-rigid poses used to blow up geometrically (1e27 m)."""
    a = pose((0, 0, 0), (0.0, 0.0, 0.0))
    b = pose((0, 0, 1), (0.001, 0.0, 0.0))  # 1 degree and 1 mm per frame
    b[:3, :3] *= 1.0 + 1e-6  # rounding from many products
    history = [a, b]
    for _ in range(300):
        history = [history[-1], constant_velocity(history)]
    r = history[-1][:3, :3]
    assert np.abs(r @ r.T - np.eye(3)).max() < 1e-9
    assert abs(np.linalg.det(r) - 1.0) < 1e-9
    assert np.abs(history[-1][:3, 3]).max() < 0.3  # at most 1 mm per frame for 300 frames
