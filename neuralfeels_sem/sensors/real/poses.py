"""Poses in config files: [x, y, z, rx, ry, rz] (metres, rotation vector in radians) <-> 4x4."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation


def pose_from_vector(vector: Sequence[float]) -> np.ndarray:
    """[x, y, z, rx, ry, rz] -> 4x4 a_T_b. A 16-vector is read as a row-major 4x4 matrix."""
    v = np.asarray(vector, dtype=np.float64)
    if v.shape == (16,):
        return v.reshape(4, 4).copy()
    if v.shape != (6,):
        raise ValueError(f"a pose vector needs 6 values [x, y, z, rx, ry, rz] or 16, got {v.shape}")
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec(v[3:]).as_matrix()
    pose[:3, 3] = v[:3]
    return pose


def vector_from_pose(pose: np.ndarray) -> list[float]:
    """4x4 rigid transform -> [x, y, z, rx, ry, rz]."""
    if pose.shape != (4, 4):
        raise ValueError(f"pose must be 4x4, got {pose.shape}")
    rotvec = Rotation.from_matrix(pose[:3, :3]).as_rotvec()
    return [float(x) for x in (*pose[:3, 3], *rotvec)]
