"""A painted sphere seen by an RGB-D camera, ray-cast exactly: a body whose turn its
shape cannot show (a sphere's SDF does not change when it spins) but its paint can.
Used by the colour-tracking tests and the pose benchmark (no renderer needed)."""

from __future__ import annotations

import numpy as np
import torch

from neuralfeels_sem.core.frame import CameraReading, Frame
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.mapping.se3 import se3_exp

RADIUS = 0.04
CENTRE = np.array([0.0, 0.0, 0.2])  # in front of the camera (at the world origin, +z)
PALETTE = np.array([[220, 60, 60], [50, 110, 220], [230, 200, 60], [80, 180, 90]], np.float64)
INTRINSICS = Intrinsics.from_fov(160, 120, 50.0)


def paint(q: np.ndarray) -> np.ndarray:
    """(N, 3) object-frame surface points -> (N, 3) RGB: patches by longitude and height."""
    lon = np.floor(3.0 * (np.arctan2(q[:, 1], q[:, 0]) + np.pi) / np.pi).astype(int)
    band = (q[:, 2] > 0.3 * RADIUS).astype(int) + (q[:, 2] < -0.3 * RADIUS)
    return PALETTE[(lon + 2 * band) % len(PALETTE)]


def render(world_T_object: np.ndarray) -> CameraReading:
    """The sphere centred at world_T_object's origin, lit from the camera (shaded)."""
    k = INTRINSICS
    v, u = np.mgrid[0 : k.height, 0 : k.width]
    rays = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u, float)], -1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    centre = world_T_object[:3, 3]
    along = rays @ centre
    disc = along**2 - centre @ centre + RADIUS**2
    hit = disc > 0
    t = np.where(hit, along - np.sqrt(np.maximum(disc, 0.0)), 0.0)
    points = rays * t[..., None]
    depth = np.where(hit, points[..., 2], 0.0).astype(np.float32)
    rgb = np.full((k.height, k.width, 3), 90, np.uint8)
    q = (points[hit] - centre) @ world_T_object[:3, :3]
    shade = 0.6 + 0.4 * np.abs((points[hit, 2] - centre[2]) / RADIUS)  # facing the camera
    rgb[hit] = np.clip(paint(q) * shade[:, None], 0, 255).astype(np.uint8)
    return CameraReading(rgb=rgb, depth=depth, intrinsics=k, world_T_camera=np.eye(4), mask=hit)


def sphere_sdf(x: torch.Tensor) -> torch.Tensor:
    return x.norm(dim=1) - RADIUS


def turning(frames: int, deg_per_frame: float, axis=(0.3, 1.0, 0.2)) -> list[np.ndarray]:
    """world_T_object turning about `axis` through the sphere's centre."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    poses = []
    for k in range(frames):
        pose = se3_exp(np.concatenate([np.zeros(3), np.deg2rad(deg_per_frame * k) * axis]))
        pose[:3, 3] = CENTRE
        poses.append(pose)
    return poses


def frame_of(k: int, world_T_object: np.ndarray) -> Frame:
    return Frame(
        index=k,
        time_s=0.1 * k,
        world_T_object=world_T_object,
        gt_world_T_object=world_T_object,
        camera=render(world_T_object),
    )
