"""Object pose from ArUco markers in a rendered view with a known pose."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.geometry import Intrinsics, look_at
from neuralfeels_sem.sensors.real.aruco_pose import ArucoObjectPose, aruco_dictionary
from neuralfeels_sem.sensors.real.poses import pose_from_vector, vector_from_pose
from tests.sensors.real.synthetic_views import marker_texture, render_plane

INTR = Intrinsics(fx=600.0, fy=600.0, cx=319.5, cy=239.5, width=640, height=480)
MARKERS = {3: [0.03, 0.0, 0.0, 0.0, np.pi / 2, 0.0], 7: [0.0, 0.0, 0.03, 0.0, 0.0, 0.0]}


def test_pose_vector_round_trip() -> None:
    v = [0.1, -0.2, 0.3, 0.4, -0.5, 0.6]
    np.testing.assert_allclose(vector_from_pose(pose_from_vector(v)), v, atol=1e-12)
    np.testing.assert_array_equal(pose_from_vector(np.eye(4).ravel()), np.eye(4))


def test_two_markers_give_the_object_pose_within_two_millimetres() -> None:
    dictionary = aruco_dictionary("DICT_4X4_50")
    world_T_camera = look_at(np.array([0.2, -0.15, 0.18]), np.zeros(3))
    world_T_object = pose_from_vector([0.01, -0.02, 0.015, 0.1, -0.2, 0.3])
    camera_T_object = np.linalg.inv(world_T_camera) @ world_T_object
    image = np.full((INTR.height, INTR.width, 3), 90, np.uint8)
    for marker_id, vec in MARKERS.items():
        texture, to_plane = marker_texture(dictionary, marker_id, 0.04)
        render_plane(image, texture, to_plane, camera_T_object @ pose_from_vector(vec), INTR)
    estimator = ArucoObjectPose(MARKERS, marker_length_m=0.04)
    estimate = estimator.estimate(image, INTR, world_T_camera)
    assert estimate is not None
    assert np.linalg.norm(estimate[:3, 3] - world_T_object[:3, 3]) < 2e-3
    angle = np.arccos(
        np.clip((np.trace(estimate[:3, :3].T @ world_T_object[:3, :3]) - 1) / 2, -1, 1)
    )
    assert np.rad2deg(angle) < 1.0


def test_no_known_marker_gives_none() -> None:
    image = np.full((INTR.height, INTR.width, 3), 90, np.uint8)
    assert ArucoObjectPose(MARKERS).estimate(image, INTR, np.eye(4)) is None
