"""Camera and tactile point clouds land on the analytic sphere in the object frame."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.perception.pointcloud import (
    camera_points,
    sensor_origin_and_axis,
    tactile_points,
)
from tests.mapping.synthetic import RADIUS, camera_reading, digit_reading, object_pose


def test_camera_points_lie_on_sphere_in_object_frame() -> None:
    pose = object_pose()
    reading = camera_reading(pose, np.array([1.0, 0.5, 0.3]))
    pts = camera_points(reading, pose)
    assert len(pts) > 500
    assert np.abs(np.linalg.norm(pts, axis=1) - RADIUS).max() < 0.5e-3
    # Only the visible hemisphere: every point faces the camera.
    origin, _ = sensor_origin_and_axis(reading.world_T_camera, pose)
    assert np.all(np.einsum("ij,ij->i", pts, origin - pts) > 0)


def test_wrong_pose_moves_points_off_the_sphere() -> None:
    """Guards against a silently ignored pose: identity instead of world_T_object fails."""
    pose = object_pose()
    reading = camera_reading(pose, np.array([0.0, 1.0, 0.0]))
    wrong = np.abs(np.linalg.norm(camera_points(reading, np.eye(4)), axis=1) - RADIUS)
    assert wrong.mean() > 0.05


def test_camera_mask_is_applied() -> None:
    pose = object_pose()
    reading = camera_reading(pose, np.array([0.0, 0.0, 1.0]))
    reading.mask[:, : reading.mask.shape[1] // 2] = False
    half = camera_points(reading, pose)
    full = camera_points(reading, pose, use_mask=False)
    assert 0 < len(half) < len(full)


def test_tactile_points_lie_on_sphere_inside_gel_range() -> None:
    pose = object_pose()
    direction = np.array([0.2, -0.7, 0.4])
    reading = digit_reading("index", pose, direction, press=0.002)
    pts = tactile_points(reading, reading.gt_depth, pose)
    assert len(pts) > 100
    assert np.abs(np.linalg.norm(pts, axis=1) - RADIUS).max() < 0.5e-3
    # The patch is centred on the touch direction and the sensor axis points into the sphere.
    centre = pts.mean(axis=0) / np.linalg.norm(pts.mean(axis=0))
    assert centre @ (direction / np.linalg.norm(direction)) > 0.99
    origin, axis = sensor_origin_and_axis(reading.world_T_sensor, pose)
    assert axis @ (-origin / np.linalg.norm(origin)) == pytest.approx(1.0, abs=1e-9)
    # Contact depth along +z is within the press range of the gel.
    depths = (pts - origin) @ axis
    assert depths.min() >= GEL_DISTANCE_M - 0.002 - 1e-6 and depths.max() <= GEL_DISTANCE_M


def test_no_contact_gives_no_points() -> None:
    pose = object_pose()
    reading = digit_reading(
        "thumb", pose, np.array([1.0, 0.0, 0.0]), press=-0.001
    )  # 1 mm short of the gel
    assert not reading.gt_depth.any()
    assert tactile_points(reading, reading.gt_depth, pose).shape == (0, 3)


def test_sensor_origin_roundtrip() -> None:
    pose = object_pose()
    reading = digit_reading("ring", pose, np.array([0.0, 0.0, -1.0]))
    origin, _ = sensor_origin_and_axis(reading.world_T_sensor, pose)
    world = pose @ np.append(origin, 1.0)
    np.testing.assert_allclose(world[:3], reading.world_T_sensor[:3, 3], atol=1e-12)
    np.testing.assert_allclose(
        invert_pose(pose) @ reading.world_T_sensor @ np.array([0, 0, 0, 1.0]),
        np.append(origin, 1.0),
        atol=1e-12,
    )
