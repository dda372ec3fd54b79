"""Pose sources (`mapping.pose`): gt, and tracked poses with their error metrics and state."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import torch
import trimesh

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import transform_points
from neuralfeels_sem.mapping.pose_error import average_3d_error, closest_point_error
from neuralfeels_sem.mapping.pose_source import PoseSource, TrackedPose, build_pose_source
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig, se3_exp
from neuralfeels_sem.objects.material_object import MaterialObject


def egg() -> MaterialObject:
    """An ellipsoid with a bump: no symmetry a small motion could slide along."""
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v = mesh.vertices * np.array([0.035, 0.025, 0.018])
    v[:, 2] += 0.006 * np.exp(-((v[:, 0] - 0.02) ** 2 + v[:, 1] ** 2) / 0.0001)
    mesh = trimesh.Trimesh(v, mesh.faces)
    labels = (mesh.triangles_center[:, 0] > 0).astype(int)
    return MaterialObject("egg", mesh, labels, ("plastic", "fabric"))


class FakeMapper:
    """The MapView a pose source reads from OnlineMapper: frame_points, sdf, has_surface.

    Observes the half of the object facing +x, at the frame's ground-truth pose; `sdf`
    (None: no field) stands in for the learned field."""

    def __init__(
        self, obj: MaterialObject, points: int = 600, has_surface: bool = True, sdf=None
    ) -> None:
        self.obj_points = obj.sample_surface(4 * points, seed=1)[0]
        self.points = points
        self.has_surface = has_surface
        self._sdf = sdf

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return self._sdf(x)

    def frame_points(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        assert np.array_equal(world_T_object, np.eye(4))  # world-frame points
        if self.points == 0:
            return {}
        world = transform_points(frame.gt_world_T_object, self.obj_points)
        facing = world[world[:, 0] > frame.gt_world_T_object[0, 3]][: self.points]
        return {"camera": facing[:-50], "index": facing[-50:]}


def trajectory(frames: int) -> list[np.ndarray]:
    poses = []
    for k in range(frames):
        t = se3_exp(np.array([0, 0, 0, 0.03 * np.sin(0.4 * k), 0.02, np.deg2rad(3.0) * k]))
        t[:3, 3] = (0.001 * k, 0.0005 * k, 0.12)
        poses.append(t)
    return poses


def frame_at(k: int, gt: np.ndarray) -> Frame:
    # world_T_object is the simulator's pose: a tracked source may read it on frame 0 only.
    return Frame(index=k, time_s=0.1 * k, world_T_object=gt, gt_world_T_object=gt)


@pytest.fixture(scope="module")
def obj() -> MaterialObject:
    return egg()


def test_gt_source_and_builder(obj) -> None:
    gt = build_pose_source("gt", obj)
    assert type(gt) is PoseSource and gt.metrics() == {}
    f = frame_at(0, trajectory(1)[0])
    np.testing.assert_array_equal(gt.estimate(f, None), f.world_T_object)
    np.testing.assert_allclose(gt.field_T_gt_object(), np.eye(4), atol=1e-12)
    assert isinstance(build_pose_source("track", obj), TrackedPose)
    assert build_pose_source("track_known_shape", obj).name == "track_known_shape"
    with pytest.raises(ConfigError, match="mapping.pose"):
        build_pose_source("vicon", obj)
    with pytest.raises(ConfigError, match="ground-truth object mesh"):
        build_pose_source("track_known_shape", None)


def test_average_3d_error() -> None:
    pts = np.random.default_rng(0).normal(size=(100, 3))
    a = np.eye(4)
    b = np.eye(4)
    b[:3, 3] = (0.003, 0.0, 0.004)
    assert average_3d_error(a, b, pts) == pytest.approx(0.005)
    assert average_3d_error(a, a, pts) == 0.0


def test_closest_point_error_is_blind_to_a_symmetric_spin() -> None:
    """A cylinder's spin about its axis moves its points along its surface: the average 3D
    error counts it, the closest-point error does not; a shift both count."""
    ring = np.random.default_rng(0).uniform(0, 2 * np.pi, 4000)
    height = np.random.default_rng(1).uniform(-0.05, 0.05, 4000)
    pts = np.stack([0.02 * np.cos(ring), height, 0.02 * np.sin(ring)], axis=1)
    spun = se3_exp(np.array([0, 0, 0, 0, np.deg2rad(60.0), 0]))
    assert average_3d_error(spun, np.eye(4), pts) > 0.015
    assert closest_point_error(spun, np.eye(4), pts) < 1.5e-3  # the samples' spacing
    shifted = np.eye(4)
    shifted[:3, 3] = (0.004, 0.0, 0.0)
    assert closest_point_error(shifted, np.eye(4), pts) > 2e-3


def known_shape_source(obj: MaterialObject) -> TrackedPose:
    return TrackedPose("track_known_shape", obj, known_shape_resolution=48)


def test_known_shape_tracking_follows_the_trajectory(obj, tmp_path) -> None:
    source = known_shape_source(obj)
    mapper = FakeMapper(obj)
    poses = trajectory(8)
    for k, gt in enumerate(poses):
        # Frame 0 sets the origin; after it the frame's own pose must not leak in.
        f = frame_at(k, gt)
        if k:
            f.world_T_object = np.eye(4)
        est = source.estimate(f, mapper)
        assert average_3d_error(est, gt, obj.mesh.vertices) < 1e-3
        np.testing.assert_allclose(source.field_T_gt_object(), np.linalg.inv(est) @ gt, atol=1e-12)
    m = source.metrics()
    assert m["pose_frames_tracked"] == 7 and m["pose_frames_kept"] == {}
    assert len(m["pose_error_curve"]) == 8 and m["pose_error_curve"][0][2] == 0.0
    assert m["pose_error_mm"] < 1.0 and m["pose_error_max_mm"] >= m["pose_error_mm"]
    source.write_pictures(tmp_path, dpi=50)
    assert (tmp_path / "pose_error.png").stat().st_size > 0


def test_state_resumes_the_same_estimates(obj) -> None:
    poses = trajectory(6)
    mapper = FakeMapper(obj)
    straight = known_shape_source(obj)
    for k, gt in enumerate(poses):
        last = straight.estimate(frame_at(k, gt), mapper)
    first = known_shape_source(obj)
    for k, gt in enumerate(poses[:3]):
        first.estimate(frame_at(k, gt), mapper)
    resumed = known_shape_source(obj)
    resumed.load_state(first.state())
    for k, gt in enumerate(poses[3:], start=3):
        again = resumed.estimate(frame_at(k, gt), mapper)
    np.testing.assert_allclose(again, last, atol=1e-9)
    np.testing.assert_allclose(
        resumed.metrics()["pose_error_curve"], straight.metrics()["pose_error_curve"], atol=1e-9
    )


def test_track_keeps_the_prediction_until_the_field_has_a_surface(obj) -> None:
    source = TrackedPose("track", obj)
    mapper = FakeMapper(obj, has_surface=False)
    poses = trajectory(3)
    for k, gt in enumerate(poses):
        est = source.estimate(frame_at(k, gt), mapper)
    np.testing.assert_array_equal(est, poses[0])  # no motion known yet: stays put
    assert source.metrics()["pose_frames_kept"] == {"no surface learned yet": 2}


def test_track_aligns_to_the_mappers_field(obj) -> None:
    """`track` reads mapper.sdf: here the exact object SDF stands in for a trained field."""
    grid = known_shape_source(obj)._sdf_fn(None)
    mapper = FakeMapper(obj, sdf=grid)
    source = TrackedPose("track", obj)
    for k, gt in enumerate(trajectory(6)):
        est = source.estimate(frame_at(k, gt), mapper)
    assert average_3d_error(est, gt, obj.mesh.vertices) < 1e-3


def test_frame_with_too_few_points_keeps_the_prediction(obj, caplog) -> None:
    source = TrackedPose(
        "track_known_shape",
        obj,
        PoseTracker(TrackerConfig(min_points=100)),
        known_shape_resolution=48,
    )
    poses = trajectory(3)
    source.estimate(frame_at(0, poses[0]), FakeMapper(obj))
    with caplog.at_level(logging.WARNING):
        est = source.estimate(frame_at(1, poses[1]), FakeMapper(obj, points=60))
    np.testing.assert_array_equal(est, poses[0])  # the prediction from one pose
    assert "too few points (60 < 100)" in caplog.text  # 10 camera and 50 touch points
    assert source.metrics()["pose_frames_kept"] == {"too few points": 1}


def test_bad_construction(obj) -> None:
    with pytest.raises(ValueError):
        TrackedPose("gt", obj)
    with pytest.raises(ValueError):
        TrackedPose("track_known_shape", None)


def test_tracker_config_builds_the_tracker_only_for_tracking_modes(obj) -> None:
    from neuralfeels_sem.configs import to_config
    from tests.helpers import compose_config

    cfg = compose_config(
        [
            "mapping.pose=track",
            "mapping.tracker.source_weights.camera=0",
            "mapping.tracker.source_weights.tactile=1",
        ]
    )
    config = to_config(TrackerConfig, cfg.mapping.tracker)
    source = build_pose_source(cfg.mapping.pose, obj, config)
    tracker = source.tracker
    assert isinstance(tracker, PoseTracker)
    assert tracker.source_weight("camera") == 0.0 and tracker.source_weight("thumb") == 1.0
    assert not hasattr(build_pose_source("gt", obj, config), "tracker")
    with pytest.raises(ValueError, match="robust_loss"):
        TrackerConfig(robust_loss="l1")
