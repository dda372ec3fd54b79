"""One camera convention for the whole project: OpenCV.

Camera frame: +x right, +y down, +z forward (looking into the scene); depth is the
z coordinate in metres, 0 where invalid. Poses are 4x4 homogeneous matrices named
`a_T_b` (maps points in frame b to frame a), e.g. `world_T_camera`.

Renderers that use OpenGL (pyrender: +y up, looking along -z) convert at their
boundary with `opengl_T_opencv`, and nowhere else.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# Pose of the OpenCV camera frame expressed in the OpenGL camera frame (flip y and z).
OPENGL_T_OPENCV = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of `width` x `height`."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @classmethod
    def from_fov(cls, width: int, height: int, fov_y_deg: float) -> Intrinsics:
        fy = 0.5 * height / np.tan(np.deg2rad(fov_y_deg) / 2.0)
        return cls(
            fx=fy, fy=fy, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0, width=width, height=height
        )

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("fx", "fy", "cx", "cy", "width", "height")}


def invert_pose(a_T_b: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (no general matrix inverse needed)."""
    check_pose(a_T_b, "pose")
    rot, trans = a_T_b[:3, :3], a_T_b[:3, 3]
    out = np.eye(4, dtype=a_T_b.dtype)
    out[:3, :3] = rot.T
    out[:3, 3] = -rot.T @ trans
    return out


def orthonormalize_pose(pose: np.ndarray) -> np.ndarray:
    """The nearest rigid transform: the rotation block projected onto SO(3) (SVD).

    Products of poses accumulate rounding; a pose whose rotation is slightly off SO(3) is
    inverted wrongly by `invert_pose` (a transpose), and repeated extrapolation then
    grows the error geometrically.
    """
    pose = np.asarray(pose, dtype=np.float64)
    if np.abs(pose[:3, :3] @ pose[:3, :3].T - np.eye(3)).max() < 1e-12:
        return pose.copy()  # already rigid: keep it bit for bit
    u, _, vt = np.linalg.svd(pose[:3, :3])
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:  # a reflection: flip the least significant axis
        u[:, -1] *= -1
        rotation = u @ vt
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = pose[:3, 3]
    return out


def check_pose(pose: np.ndarray, name: str) -> None:
    if not isinstance(pose, np.ndarray) or pose.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 array, got {getattr(pose, 'shape', type(pose))}")


def transform_points(a_T_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Apply a 4x4 transform to (N, 3) points."""
    check_pose(a_T_b, "transform")
    if points_b.ndim != 2 or points_b.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {points_b.shape}")
    return points_b @ a_T_b[:3, :3].T + a_T_b[:3, 3]


def pixel_grid(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centre coordinates (u right, v down), each (height, width)."""
    return np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))


def backproject(
    depth: np.ndarray, intrinsics: Intrinsics, mask: np.ndarray | None = None
) -> np.ndarray:
    """Depth image (metres, OpenCV z) -> (N, 3) points in the camera frame.

    Pixels with depth <= 0, non-finite depth or outside `mask` are dropped.
    """
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise ValueError(
            f"depth shape {depth.shape} does not match intrinsics {intrinsics.height}x{intrinsics.width}"
        )
    valid = np.isfinite(depth) & (depth > 0)
    if mask is not None:
        if mask.shape != depth.shape:
            raise ValueError(f"mask shape {mask.shape} does not match depth shape {depth.shape}")
        valid &= mask.astype(bool)
    v, u = np.nonzero(valid)
    z = depth[v, u]
    x = (u - intrinsics.cx) * z / intrinsics.fx
    y = (v - intrinsics.cy) * z / intrinsics.fy
    return np.stack([x, y, z], axis=1)


def project(points_cam: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """(N, 3) camera-frame points -> (N, 2) pixel coordinates (u, v)."""
    if points_cam.ndim != 2 or points_cam.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {points_cam.shape}")
    z = points_cam[:, 2]
    u = intrinsics.fx * points_cam[:, 0] / z + intrinsics.cx
    v = intrinsics.fy * points_cam[:, 1] / z + intrinsics.cy
    return np.stack([u, v], axis=1)


WORLD_UP = (0.0, 0.0, 1.0)


def look_at(eye: np.ndarray, target: np.ndarray, up: Sequence[float] = WORLD_UP) -> np.ndarray:
    """world_T_camera for an OpenCV camera at `eye` looking at `target`."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    forward = target - eye
    norm = np.linalg.norm(forward)
    if norm < 1e-12:
        raise ValueError("look_at: eye and target coincide")
    z = forward / norm
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:  # looking along `up`: pick any perpendicular
        x = np.cross(z, np.array([1.0, 0.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    return pose


def rotation_matrix(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """3x3 rotation about a (not necessarily unit) axis, Rodrigues' formula."""
    axis = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(axis)
    if n < 1e-12:
        raise ValueError("rotation axis must be non-zero")
    k = axis / n
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * kx + (1 - np.cos(angle_rad)) * (kx @ kx)
