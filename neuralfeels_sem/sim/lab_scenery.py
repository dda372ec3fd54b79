"""The static lab around the simulated hand, as the RGB-D camera sees it.

A real view of an in-hand rig is never the object alone: a table under the hand, a wall or
curtain behind it and the arm the hand is mounted on are all within a depth camera's range.
The camera renderer draws these (sensor.rgbd.table_height, backdrop_distance, mount) so that
a segmentation from depth has to tell the object apart from them; none is ever in the
object's ground-truth mask.
"""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.sim.hand_model import PALM_CENTRE, PALM_HALF

MOUNT_LENGTH_M = 0.12  # wrist flange and the end of the arm behind the palm
BACKDROP_SIZE_M = 2.5  # wide and tall enough to fill the view behind the hand


def backdrop(world_T_camera: np.ndarray, distance: float) -> tuple[trimesh.Trimesh, np.ndarray]:
    """A vertical wall facing the camera, `distance` metres from it along its level view direction."""
    if distance <= 0:
        raise ValueError(f"backdrop distance must be > 0, got {distance}")
    view = np.asarray(world_T_camera, float)[:3, 2].copy()
    view[2] = 0.0
    if np.linalg.norm(view) < 1e-6:
        raise ValueError(
            "a camera looking straight down has no backdrop; set backdrop_distance=null"
        )
    view /= np.linalg.norm(view)
    pose = np.eye(4)
    # Box z (its thin side) along the view; x horizontal, y vertical.
    pose[:3, 2] = view
    pose[:3, 1] = (0.0, 0.0, 1.0)
    pose[:3, 0] = np.cross(pose[:3, 1], view)
    pose[:3, 3] = world_T_camera[:3, 3] + (distance + 0.01) * view
    pose[2, 3] = world_T_camera[2, 3]
    wall = trimesh.creation.box(extents=(BACKDROP_SIZE_M, BACKDROP_SIZE_M, 0.02))
    return wall, pose


def hand_mount(world_T_palm: np.ndarray) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The wrist and arm end the hand is bolted to, behind the palm (palm -z)."""
    extents = (2 * PALM_HALF[0], 1.4 * PALM_HALF[1], MOUNT_LENGTH_M)
    palm_T_mount = np.eye(4)
    palm_T_mount[:3, 3] = (
        PALM_CENTRE[0],
        PALM_CENTRE[1],
        PALM_CENTRE[2] - PALM_HALF[2] - MOUNT_LENGTH_M / 2,
    )
    return trimesh.creation.box(extents=extents), np.asarray(world_T_palm, float) @ palm_T_mount
