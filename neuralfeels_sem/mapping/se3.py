"""Rigid motions as se(3) vectors and the constant-velocity motion model of pose tracking.

xi = (v, w): translation part v and rotation vector w; se3_exp / se3_log map between it
and 4x4 rigid transforms (Rodrigues, closed form).
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.geometry import check_pose, invert_pose, orthonormalize_pose


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """xi = (v, w) (6,) -> 4x4 rigid transform (Rodrigues, exact for any angle)."""
    xi = np.asarray(xi, dtype=np.float64)
    if xi.shape != (6,):
        raise ValueError(f"se3_exp needs a (6,) vector, got {xi.shape}")
    v, w = xi[:3], xi[3:]
    theta = float(np.linalg.norm(w))
    k = _skew(w)
    if theta < 1e-8:
        rot = np.eye(3) + k
        jac = np.eye(3) + 0.5 * k
    else:
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / theta**2
        c = (theta - np.sin(theta)) / theta**3
        rot = np.eye(3) + a * k + b * (k @ k)
        jac = np.eye(3) + b * k + c * (k @ k)
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = jac @ v
    return out


def se3_log(pose: np.ndarray) -> np.ndarray:
    """4x4 rigid transform -> xi = (v, w) (6,), the inverse of se3_exp (angles below pi)."""
    check_pose(pose, "pose")
    rot = pose[:3, :3]
    cos = np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos))
    vee = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if theta < 1e-8:
        w = 0.5 * vee
    else:
        w = theta / (2.0 * np.sin(theta)) * vee
    k = _skew(w)
    if theta < 1e-8:
        jac_inv = np.eye(3) - 0.5 * k
    else:
        half = 0.5 * theta
        jac_inv = np.eye(3) - 0.5 * k + (1.0 - half / np.tan(half)) / theta**2 * (k @ k)
    return np.concatenate([jac_inv @ pose[:3, 3], w])


def constant_velocity(poses: list[np.ndarray]) -> np.ndarray:
    """Next world_T_object if the last body-frame motion repeats (the last pose when alone)."""
    if not poses:
        raise ValueError("constant_velocity needs at least one pose")
    if len(poses) == 1:
        return poses[-1].copy()
    step = invert_pose(poses[-2]) @ poses[-1]
    return orthonormalize_pose(poses[-1] @ step)


def interpolate_pose(start: np.ndarray, end: np.ndarray, share: float) -> np.ndarray:
    """The pose `share` of the way from `start` to `end` (0: start, 1: end) along the
    constant body-frame motion between them (geodesic on SE(3); rotations below pi)."""
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"share={share} must be in [0, 1]")
    motion = se3_log(invert_pose(start) @ end)
    return orthonormalize_pose(start @ se3_exp(share * motion))
