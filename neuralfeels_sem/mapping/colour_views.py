"""Colour consistency with earlier camera views: a motion cue that does not use the map.

A turn of a smooth body (a pebble) moves few of its camera points off its surface, so an
alignment to the learned field alone cannot see it, and the field learned with a short
turn then agrees with it. The colours the body shows can: a pixel of the current frame,
placed on the object by the pose being solved for, must show the colour the same object
point had in an earlier view. The residual of one pixel and colour channel k is

    r = scale_m * (F_ref_k(project(camera_T_world_ref @ world_T_object_ref @ q)) - c_k)

with q the pixel's object-frame point (the quantity the tracker moves), F_ref the earlier
view's colour features (bilinear) and c the pixel's own. It is a function of q alone, so
the tracker treats it like the SDF: one autograd pass gives every residual's gradient in
q and its Jacobian row is again [g, q x g].

Features are chromaticity (r, g over r + g + b): the lights stay put while the object
turns, so shading changes a point's brightness from view to view but hardly its hue.
Colour is used here as a motion cue only, never as a material cue (the simulator paints
materials in palette colours; real objects carry texture).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
import torch
from torch import Tensor

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.core.geometry import Intrinsics, invert_pose, transform_points

DARK = 30.0  # r + g + b below this (of 765): too dark for a reliable hue
MARGIN_PX = 4  # kept around the object's pixels: the bilinear lookup's neighbours


def colour_features(rgb: np.ndarray, blur_px: float) -> np.ndarray:
    """(H, W, 2) float32 chromaticity of an RGB uint8 image, Gaussian-blurred by blur_px
    (a wider basin than the aliased patch borders give); dark pixels get grey."""
    x = rgb.astype(np.float32)
    if blur_px > 0:
        x = cv2.GaussianBlur(x, (0, 0), blur_px)
    total = x.sum(axis=2, keepdims=True)
    chroma = x[..., :2] / np.maximum(total, DARK)
    return np.where(total >= DARK, chroma, 1.0 / 3.0).astype(np.float32)


def pixels_of(reading: CameraReading, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image rows and columns (int) of world points back-projected from this camera's pixels."""
    cam = transform_points(invert_pose(reading.world_T_camera), points_world)
    k = reading.intrinsics
    cols = np.rint(k.fx * cam[:, 0] / cam[:, 2] + k.cx).astype(int)
    rows = np.rint(k.fy * cam[:, 1] / cam[:, 2] + k.cy).astype(int)
    return np.clip(rows, 0, k.height - 1), np.clip(cols, 0, k.width - 1)


@dataclass
class ColourView:
    """One camera frame's object pixels: their world points, colour features, and the view
    as a reference for later frames (features, eroded object mask, depth, poses), kept for
    the object's box in the image only (a run keeps many keyframes)."""

    index: int
    points_world: np.ndarray  # (P, 3) the object pixels' world points
    colours: np.ndarray  # (P, C) their features
    features: Tensor  # (C, h, w) float32, the object's box of the image
    mask: np.ndarray  # (h, w) bool: object pixels away from the silhouette
    depth: np.ndarray  # (h, w) metres
    origin: tuple[int, int]  # image (row, column) of the box's first pixel
    camera_T_world: np.ndarray
    intrinsics: Intrinsics
    world_T_object: np.ndarray  # the pose the view was mapped with (set once known)

    @classmethod
    def of(
        cls,
        index: int,
        reading: CameraReading,
        points_world: np.ndarray,
        blur_px: float,
        erode_px: int,
    ) -> ColourView:
        rows, cols = pixels_of(reading, points_world)
        feats = colour_features(reading.rgb, blur_px)
        mask = np.zeros(reading.depth.shape, np.uint8)
        mask[rows, cols] = 1
        if erode_px > 0:
            mask = cv2.erode(mask, np.ones((2 * erode_px + 1,) * 2, np.uint8))
        h, w = mask.shape
        r0, c0 = max(int(rows.min()) - MARGIN_PX, 0), max(int(cols.min()) - MARGIN_PX, 0)
        box = np.s_[
            r0 : min(int(rows.max()) + MARGIN_PX + 1, h),
            c0 : min(int(cols.max()) + MARGIN_PX + 1, w),
        ]
        return cls(
            index=index,
            points_world=np.asarray(points_world, np.float64),
            colours=feats[rows, cols],
            features=torch.from_numpy(np.ascontiguousarray(feats[box].transpose(2, 0, 1))),
            mask=mask[box].astype(bool),
            depth=np.array(reading.depth[box], np.float32),
            origin=(r0, c0),
            camera_T_world=invert_pose(reading.world_T_camera),
            intrinsics=reading.intrinsics,
            world_T_object=np.eye(4),
        )

    def as_reference(self) -> ColourView:
        """The view once it only serves as a reference: its pixels' points and colours
        (used while it is the current frame) are dropped, the image box kept."""
        self.points_world = np.zeros((0, 3))
        self.colours = np.zeros((0, self.colours.shape[1]), np.float32)
        return self

    def state(self) -> dict:
        """A reference view as tensors and plain values (checkpoints load weights-only)."""
        return {
            "index": int(self.index),
            "features": self.features.clone(),
            "mask": torch.from_numpy(self.mask.copy()),
            "depth": torch.from_numpy(self.depth.copy()),
            "origin": [int(v) for v in self.origin],
            "camera_T_world": torch.from_numpy(np.array(self.camera_T_world, np.float64)),
            "intrinsics": {
                k: v.item() if hasattr(v, "item") else v
                for k, v in self.intrinsics.to_dict().items()
            },
            "world_T_object": torch.from_numpy(np.array(self.world_T_object, np.float64)),
        }

    @classmethod
    def from_state(cls, state: dict) -> ColourView:
        channels = int(state["features"].shape[0])
        return cls(
            index=int(state["index"]),
            points_world=np.zeros((0, 3)),
            colours=np.zeros((0, channels), np.float32),
            features=state["features"].clone(),
            mask=state["mask"].numpy().copy(),
            depth=state["depth"].numpy().copy(),
            origin=(int(state["origin"][0]), int(state["origin"][1])),
            camera_T_world=state["camera_T_world"].numpy().copy(),
            intrinsics=Intrinsics(**state["intrinsics"]),
            world_T_object=state["world_T_object"].numpy().copy(),
        )


def _project(camera_T_object: np.ndarray, q: np.ndarray, k: Intrinsics):
    cam = q @ camera_T_object[:3, :3].T + camera_T_object[:3, 3]
    z = np.maximum(cam[:, 2], 1e-6)
    return k.fx * cam[:, 0] / z + k.cx, k.fy * cam[:, 1] / z + k.cy, cam[:, 2]


def visible_in(ref: ColourView, q: np.ndarray, max_depth_gap_m: float) -> np.ndarray:
    """Which object-frame points q (P, 3) land inside `ref`'s eroded object mask at a depth
    within max_depth_gap_m of what `ref` measured there (not hidden behind the object
    itself or a finger)."""
    camera_T_object = ref.camera_T_world @ ref.world_T_object
    u, v, z = _project(camera_T_object, q, ref.intrinsics)
    h, w = ref.mask.shape
    col = np.rint(u).astype(int) - ref.origin[1]
    row = np.rint(v).astype(int) - ref.origin[0]
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h) & (z > 0)
    col, row = np.clip(col, 0, w - 1), np.clip(row, 0, h - 1)
    seen = ref.depth[row, col]
    return inside & ref.mask[row, col] & (np.abs(seen - z) <= max_depth_gap_m)


def colour_residuals(
    ref: ColourView, colours: np.ndarray, scale_m: float
) -> Callable[[Tensor], Tensor]:
    """Residual function of (P * C, 3) object-frame points (each pixel's point repeated
    once per channel, channel fastest) against `ref`: see the module docstring."""
    camera_T_object = torch.as_tensor(ref.camera_T_world @ ref.world_T_object, dtype=torch.float32)
    k = ref.intrinsics
    channels = colours.shape[1]
    target = torch.as_tensor(colours, dtype=torch.float32).reshape(-1)
    pick = torch.arange(len(target)) % channels
    height, width = ref.mask.shape
    span = torch.tensor([max(width - 1.0, 1.0), max(height - 1.0, 1.0)])
    origin = torch.tensor([float(ref.origin[1]), float(ref.origin[0])])

    def residuals(x: Tensor) -> Tensor:
        cam = x @ camera_T_object[:3, :3].T + camera_T_object[:3, 3]
        z = cam[:, 2].clamp_min(1e-6)
        uv = torch.stack([k.fx * cam[:, 0] / z + k.cx, k.fy * cam[:, 1] / z + k.cy], dim=1)
        uv = uv - origin  # into the box
        grid = (2.0 * uv / span - 1.0).reshape(1, 1, -1, 2)
        sampled = torch.nn.functional.grid_sample(
            ref.features[None], grid, mode="bilinear", padding_mode="border", align_corners=True
        )[0, :, 0, :]  # (C, rows): every channel at every row's point
        own = sampled.gather(0, pick[None, :])[0]
        return scale_m * (own - target)

    return residuals
