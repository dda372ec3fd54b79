"""Poses of a DIGIT pressing a surface: head-on at its gel centre, or tilted onto an edge."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.geometry import rotation_matrix


def pose_pressing(
    point: np.ndarray, normal: np.ndarray, press_m: float, roll_rad: float = 0.0
) -> np.ndarray:
    """world_T_sensor of a DIGIT whose gel centre is pressed `press_m` into a surface.

    `point` and `normal` (outward) are the touched surface point and its normal in the
    world frame; a negative `press_m` leaves a gap. `roll_rad` turns the sensor about
    its optical axis.
    """
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    z = -n
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    x, y = c * x + s * y, -s * x + c * y
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, y, z
    pose[:3, 3] = np.asarray(point, np.float64) + n * (GEL_DISTANCE_M - press_m)
    return pose


def pose_pressing_edge(
    point: np.ndarray,
    normal: np.ndarray,
    press_m: float,
    gel_point: tuple[float, float],
    tilt_rad: float,
    roll_rad: float = 0.0,
) -> np.ndarray:
    """world_T_sensor of a DIGIT tilted so an off-centre gel point presses `press_m` deepest.

    `gel_point` = (x, y) on the gel in metres from its centre (sensor frame). The sensor is
    turned by `tilt_rad` about the gel-plane axis through that point perpendicular to its
    offset, lifting the gel centre off the surface: the imprint is a strip along the
    sensor edge, as a tilted fingertip pad makes on a narrow object.
    """
    offset = np.array([gel_point[0], gel_point[1], 0.0])
    if np.linalg.norm(offset) < 1e-9:
        raise ValueError("gel_point must be off the gel centre for an edge press")
    pose = pose_pressing(point, normal, press_m, roll_rad)
    rotation = pose[:3, :3]
    pivot = pose[:3, 3] + rotation @ [0.0, 0.0, GEL_DISTANCE_M]  # the pressed gel point
    pose[:3, 3] -= rotation @ offset  # the gel point, not the centre, sits on `point`
    axis = rotation @ np.array([-offset[1], offset[0], 0.0])
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    best = None
    for sign in (1.0, -1.0):
        turn = rotation_matrix(axis, sign * tilt_rad)
        candidate = np.eye(4)
        candidate[:3, :3] = turn @ rotation
        candidate[:3, 3] = pivot + turn @ (pose[:3, 3] - pivot)
        centre = candidate[:3, :3] @ [0.0, 0.0, GEL_DISTANCE_M] + candidate[:3, 3]
        lift = float(n @ centre)  # the gel centre must move away from the surface
        if best is None or lift > best[0]:
            best = (lift, candidate)
    return best[1]
