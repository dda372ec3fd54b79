"""Analytic sphere scenes: exact camera and DIGIT depth of a sphere, no renderer.

A sphere of radius RADIUS centred at the object origin, seen by pinhole cameras orbiting it
and touched by simulated DIGITs pressed into it along chosen directions. Material ground
truth: class 1 on the upper hemisphere (object z > 0), class 0 below. Used by the mapping
tests and the mapper benchmark, where a renderer would only add cost and doubt.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.core.geometry import Intrinsics, invert_pose, look_at, rotation_matrix
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.perception.touch import TouchLabel

RADIUS = 0.04


def object_pose() -> np.ndarray:
    """A non-identity world_T_object (rotated and translated)."""
    pose = np.eye(4)
    pose[:3, :3] = rotation_matrix(np.array([0.3, -0.5, 0.8]), 0.9)
    pose[:3, 3] = [0.12, -0.05, 0.3]
    return pose


def sphere_depth(
    intrinsics: Intrinsics, camera_T_object: np.ndarray, radius: float = RADIUS
) -> np.ndarray:
    """OpenCV z-depth of the sphere (centre = object origin) per pixel, 0 where missed."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = np.stack(
        [
            (u - intrinsics.cx) / intrinsics.fx,
            (v - intrinsics.cy) / intrinsics.fy,
            np.ones(u.shape),
        ],
        -1,
    )
    dirs = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    c = camera_T_object[:3, 3]
    b = dirs @ c
    disc = b**2 - (c @ c - radius**2)
    t = b - np.sqrt(np.clip(disc, 0.0, None))
    depth = t * dirs[..., 2]
    return np.where((disc > 0) & (t > 0), depth, 0.0).astype(np.float32)


def fibonacci_directions(n: int) -> np.ndarray:
    """n nearly uniform unit vectors on the sphere."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5**0.5) * i
    r = np.sqrt(1.0 - z**2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def camera_reading(
    world_T_object: np.ndarray,
    direction_obj: np.ndarray,
    distance: float = 0.3,
    size: tuple[int, int] = (96, 72),
) -> CameraReading:
    """A camera at `distance` along `direction_obj` (object frame), looking at the sphere."""
    intr = Intrinsics.from_fov(size[0], size[1], fov_y_deg=22.0)
    eye_obj = direction_obj / np.linalg.norm(direction_obj) * distance
    up = (
        np.array([0.0, 0.0, 1.0])
        if abs(direction_obj[2]) < 0.9 * np.linalg.norm(direction_obj)
        else np.array([1.0, 0.0, 0.0])
    )
    world_T_camera = world_T_object @ look_at(eye_obj, np.zeros(3), up)
    depth = sphere_depth(intr, invert_pose(world_T_camera) @ world_T_object)
    rgb = np.zeros((*depth.shape, 3), np.uint8)
    return CameraReading(
        rgb=rgb, depth=depth, intrinsics=intr, world_T_camera=world_T_camera, mask=depth > 0
    )


def digit_reading(
    finger: str, world_T_object: np.ndarray, direction_obj: np.ndarray, press: float = 0.0015
) -> TactileReading:
    """A DIGIT whose +z axis points at the sphere centre, its gel pressed in by `press`."""
    d = direction_obj / np.linalg.norm(direction_obj)
    origin = d * (RADIUS + GEL_DISTANCE_M - press)
    up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    world_T_sensor = world_T_object @ look_at(origin, np.zeros(3), up)
    depth = sphere_depth(DIGIT_INTRINSICS, invert_pose(world_T_sensor) @ world_T_object)
    depth = np.where(depth < GEL_DISTANCE_M, depth, 0.0).astype(np.float32)
    contact = depth > 0
    material = np.where(contact, int(d[2] > 0), -1).astype(np.int16)
    image = np.full((DIGIT_INTRINSICS.height, DIGIT_INTRINSICS.width, 3), 120, np.uint8)
    return TactileReading(
        finger=finger, image=image, world_T_sensor=world_T_sensor, intrinsics=DIGIT_INTRINSICS,
        background=image.copy(), gt_contact_mask=contact, gt_depth=depth, gt_material=material,
    )  # fmt: skip


def sphere_frames(
    num_frames: int,
    touches_per_frame: int = 4,
    camera: bool = True,
    seed: int = 0,
    press: float = 0.0015,
) -> list[tuple[Frame, dict[str, TouchLabel]]]:
    """Frames orbiting the sphere with touches spread over it, each labelled by the
    hemisphere of its centre (as a classifier labels a whole patch) with confidence 0.9."""
    pose = object_pose()
    cams = fibonacci_directions(max(num_frames, 1))
    touch_dirs = fibonacci_directions(max(num_frames * touches_per_frame, 1))
    rng = np.random.default_rng(seed)
    touch_dirs = touch_dirs[rng.permutation(len(touch_dirs))]
    out = []
    for i in range(num_frames):
        tactile, labels = {}, {}
        for j in range(touches_per_frame):
            finger = FINGERS[j]
            d = touch_dirs[i * touches_per_frame + j]
            tactile[finger] = digit_reading(finger, pose, d, press=press)
            labels[finger] = TouchLabel(finger, contact=True, label=int(d[2] > 0), confidence=0.9)
        frame = Frame(
            index=i,
            time_s=0.1 * i,
            world_T_object=pose,
            tactile=tactile,
            camera=camera_reading(pose, cams[i]) if camera else None,
        )
        out.append((frame, labels))
    return out


def sphere_surface(n: int) -> np.ndarray:
    return fibonacci_directions(n) * RADIUS


def true_label(points: np.ndarray) -> np.ndarray:
    return (points[:, 2] > 0).astype(np.int64)
