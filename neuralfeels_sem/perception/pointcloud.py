"""Camera and tactile point clouds from a Frame, in the object frame.

Both sensors are OpenCV pinhole cameras (+z forward, depth = z in metres, 0 = invalid):
back-project the depth, move the points to the world with the sensor pose, then into
the object frame with the inverse of `world_T_object` (the pose used for mapping).
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.frame import CameraReading, TactileReading
from neuralfeels_sem.core.geometry import backproject, check_pose, invert_pose, transform_points


def object_T_sensor(world_T_sensor: np.ndarray, world_T_object: np.ndarray) -> np.ndarray:
    """Pose of a sensor in the object frame."""
    check_pose(world_T_sensor, "world_T_sensor")
    return invert_pose(world_T_object) @ world_T_sensor


def camera_points(
    reading: CameraReading, world_T_object: np.ndarray, use_mask: bool = True
) -> np.ndarray:
    """(N, 3) object-frame points of the camera's valid depth pixels (inside its object mask).

    Without a mask (`use_mask=False` or `reading.mask is None`) every valid pixel is kept,
    background included: only do that when the depth image shows the object alone.
    """
    mask = reading.mask if use_mask else None
    pts_cam = backproject(reading.depth, reading.intrinsics, mask)
    return transform_points(object_T_sensor(reading.world_T_camera, world_T_object), pts_cam)


def tactile_points(
    reading: TactileReading, depth: np.ndarray, world_T_object: np.ndarray
) -> np.ndarray:
    """(N, 3) object-frame contact points from a tactile contact depth (0 off-contact)."""
    pts_sensor = backproject(depth, reading.intrinsics)
    return transform_points(object_T_sensor(reading.world_T_sensor, world_T_object), pts_sensor)


def sensor_origin_and_axis(
    world_T_sensor: np.ndarray, world_T_object: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Optical centre and viewing axis (+z) of a sensor, both in the object frame."""
    pose = object_T_sensor(world_T_sensor, world_T_object)
    return pose[:3, 3].copy(), pose[:3, 2].copy()
