"""Pose tracking that does not hold is caught: frames that cannot fit, diverging solves,
too few points and unobservable directions are kept at the prediction and counted, never
reported as tracked; and the batched SDF gradient of the tracker's Jacobian is checked
against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.geometry import invert_pose, transform_points
from neuralfeels_sem.mapping.fit_check import conditioning, fit_failure, inlier_share
from neuralfeels_sem.mapping.pose_source import TrackedPose
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig, se3_exp
from tests.mapping.test_pose_source import FakeMapper, egg, frame_at, trajectory
from tests.mapping.test_pose_tracker import SPHERE_R, pose, sphere_box_sdf, surface_points


def sphere(x: torch.Tensor) -> torch.Tensor:
    return x.norm(dim=1) - SPHERE_R


def test_a_frame_that_cannot_fit_is_kept_at_the_prediction() -> None:
    """Points scattered through space (no surface explains them) are not 'tracked'."""
    cloud = np.random.default_rng(0).uniform(-0.06, 0.06, (600, 3)) + (0.0, 0.0, 0.1)
    predicted = pose((0, 0, 5), (0.0, 0.0, 0.1))
    est, info = PoseTracker().track({"camera": cloud}, sphere_box_sdf, predicted, predicted)
    assert info["skipped"].startswith("poor fit") and info["inlier_share"] < 0.5
    np.testing.assert_array_equal(est, predicted)


def test_a_good_frame_passes_the_fit_checks() -> None:
    truth = pose((4, -2, 6), (0.002, 0.0, 0.1))
    world = transform_points(truth, surface_points(800, seed=7))
    start = truth @ pose((0, 0, 2), (0.001, 0.0, 0.0))
    est, info = PoseTracker().track({"camera": world}, sphere_box_sdf, start, start)
    assert info["skipped"] is None and info["inlier_share"] > 0.99
    assert info["conditioning"] > 1e-3 and not info["degenerate"]
    np.testing.assert_allclose(est, truth, atol=2e-4)


def test_a_non_finite_field_is_rejected_as_diverged() -> None:
    world = transform_points(np.eye(4), surface_points(300))

    def broken(x: torch.Tensor) -> torch.Tensor:
        return sphere_box_sdf(x) * float("nan")

    est, info = PoseTracker().track({"camera": world}, broken, np.eye(4), np.eye(4))
    assert info["skipped"] == "diverged (non-finite SDF at the start)"
    np.testing.assert_array_equal(est, np.eye(4))


def test_a_turn_beyond_the_cap_is_rejected_as_diverged() -> None:
    truth = pose((0, 0, 40), (0.0, 0.0, 0.1))
    world = transform_points(truth, surface_points(800, seed=8))
    start = pose((0, 0, 0), (0.0, 0.0, 0.1))
    config = TrackerConfig(iterations=60, max_motion_rad=0.2, max_step_rad=0.5, prior_weight=0)
    est, info = PoseTracker(config).track({"camera": world}, sphere_box_sdf, start)
    assert info["skipped"].startswith("diverged") and "rad from the prediction" in info["skipped"]
    np.testing.assert_array_equal(est, start)


def test_unobservable_directions_need_the_prior() -> None:
    """A sphere's spin: held by the prior it is tracked (and flagged), without it rejected."""
    dirs = np.random.default_rng(5).normal(size=(500, 3))
    world = transform_points(
        pose((0, 0, 0), (0.0, 0.0, 0.1)), SPHERE_R * dirs / np.linalg.norm(dirs, axis=1)[:, None]
    )
    start = pose((0, 0, 10), (0.001, 0.0, 0.1))
    _, info = PoseTracker().track({"camera": world}, sphere, start, prior=start)
    assert info["skipped"] is None and info["degenerate"]
    est, info = PoseTracker().track({"camera": world}, sphere, start)
    assert info["skipped"].startswith("ill-conditioned")
    np.testing.assert_array_equal(est, start)


def test_fit_check_measures() -> None:
    r = torch.tensor([0.0, 0.001, 0.003, -0.004], dtype=torch.float64)
    w = torch.tensor([1.0, 1.0, 1.0, 1.0], dtype=torch.float64)
    assert inlier_share(r, w, 0.002) == 0.5
    assert inlier_share(r, w * 0, 0.002) == 0.0
    q = torch.tensor([[0.0, 0.0, 0.0]] * 3, dtype=torch.float64)
    plane = torch.tensor([[0.0, 0.0, 1.0]] * 3, dtype=torch.float64)  # slides freely in x, y
    assert conditioning(q, plane, torch.ones(3, dtype=torch.float64), 0.05) == 0.0
    assert fit_failure(0.4, 1.0, 0.5, 1e-9).startswith("poor fit")
    assert fit_failure(0.9, 0.0, 0.5, 1e-9).startswith("ill-conditioned")
    assert fit_failure(0.9, 1e-3, 0.5, 1e-9) is None
    with pytest.raises(ValueError, match="min_inlier_share"):
        TrackerConfig(min_inlier_share=1.5)
    with pytest.raises(ValueError, match="inlier_m"):
        TrackerConfig(inlier_m=0.0)


def test_a_pose_source_counts_and_notes_frames_not_tracked() -> None:
    """The run's metrics say how many frames kept the prediction, and why."""
    obj = egg()

    def far_field(x: torch.Tensor) -> torch.Tensor:  # a field that explains nothing
        return x.norm(dim=1) + 0.05

    source = TrackedPose("track", obj)
    poses = trajectory(4)
    for k, gt in enumerate(poses):
        est = source.estimate(frame_at(k, gt), FakeMapper(obj, sdf=far_field))
    np.testing.assert_allclose(est, poses[0], atol=1e-9)  # never moved: no frame fitted
    m = source.metrics()
    assert m["pose_frames_tracked"] == 0 and m["pose_frames_not_tracked"] == 3
    assert m["pose_frames_kept"] == {"poor fit": 3}
    assert m["pose_notes"] == [
        "pose: 3 frames not tracked (3 poor fit), 3 of them not mapped; 0 tracked"
    ]
    assert [row[0] for row in m["pose_fit_curve"]] == [1, 2, 3]


def residuals(tracker: PoseTracker, fn, obj_T_world: np.ndarray, pts: torch.Tensor, grad: bool):
    return tracker._linearise(fn, obj_T_world, pts, grad)


def test_jacobian_matches_finite_differences() -> None:
    """Rows [g, q x g] of the batched autograd gradient = d r / d xi of a left se(3)
    perturbation, by central differences (theseus-style numeric check); and the trial
    path without gradient gives the same residuals."""
    tracker = PoseTracker()
    world = torch.as_tensor(surface_points(200, seed=9)) + torch.tensor([0.0, 0.0, 0.1])
    obj_T_world = invert_pose(pose((3, 1, 5), (0.0, 0.0, 0.1)))
    q, r, g = residuals(tracker, sphere_box_sdf, obj_T_world, world, True)
    _, r_trial, g_trial = residuals(tracker, sphere_box_sdf, obj_T_world, world, False)
    assert g_trial is None
    torch.testing.assert_close(r_trial, r, rtol=0, atol=0)
    jac = torch.cat([g, torch.linalg.cross(q, g)], dim=1).numpy()
    numeric = np.zeros_like(jac)
    eps = 1e-5  # the tracker feeds float32 points: not much smaller
    for k in range(6):
        step = np.zeros(6)
        step[k] = eps
        plus = residuals(tracker, sphere_box_sdf, se3_exp(step) @ obj_T_world, world, False)[1]
        minus = residuals(tracker, sphere_box_sdf, se3_exp(-step) @ obj_T_world, world, False)[1]
        numeric[:, k] = ((plus - minus) / (2 * eps)).numpy()
    np.testing.assert_allclose(numeric, jac, atol=2e-3)


def test_batched_field_gradient_equals_the_fields_own() -> None:
    """One forward and one backward pass for every point give each point's own gradient
    (SemanticField.sdf_and_gradient) and the residuals of a forward pass alone."""
    from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig

    torch.manual_seed(0)
    field = SemanticField(SemanticFieldConfig(num_classes=2), bound=0.06)
    world = torch.as_tensor(surface_points(300, seed=9))
    q, r, g = residuals(PoseTracker(), field.sdf, np.eye(4), world, True)
    _, r_trial, _ = residuals(PoseTracker(), field.sdf, np.eye(4), world, False)
    sdf, grad = field.sdf_and_gradient(world.to(torch.float32), create_graph=False)
    torch.testing.assert_close(r, sdf.detach().to(torch.float64), rtol=0, atol=1e-7)
    torch.testing.assert_close(r_trial, r, rtol=0, atol=1e-7)
    torch.testing.assert_close(g, grad.to(torch.float64), rtol=1e-5, atol=1e-6)


def test_the_ground_truth_pose_adds_no_note() -> None:
    from neuralfeels_sem.mapping.pose_source import PoseSource

    assert PoseSource().notes() == [] and PoseSource().metrics() == {}
