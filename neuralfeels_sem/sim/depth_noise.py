"""RealSense-like depth noise for the simulated RGB-D camera (`sensor.rgbd.depth_noise=realsense`).

An active stereo camera (Intel RealSense D400) measures disparity, so its depth error grows
with the square of distance: sigma_z = z^2 * subpixel / (focal_px * baseline) (Grunnet-Jepsen
et al., "Tuning depth cameras for best performance", Intel RealSense white paper, eq. 1).
It also returns no depth (0) where stereo matching fails: along depth discontinuities
(the occluded band beside a foreground edge) and on surfaces seen at grazing angles, plus
a few scattered pixels. The defaults are a D435's: 50 mm baseline, 87 degree horizontal
depth field of view at 848 px wide (focal_px = 424 / tan(43.5 deg) = 447), subpixel 0.08
(the white paper's typical RMS subpixel error on a textured scene).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from neuralfeels_sem.core.geometry import Intrinsics

DEPTH_NOISE_MODELS = ("none", "realsense")  # sensor.rgbd.depth_noise


@dataclass
class RealSenseNoiseConfig:
    """sensor.rgbd.realsense: the noise model's parameters (used when depth_noise=realsense)."""

    baseline_m: float = 0.050  # D435 stereo baseline
    focal_px: float = 447.0  # D435 depth imager at 848 px, 87 degree HFOV
    subpixel: float = 0.08  # RMS disparity error in pixels
    edge_jump_m: float = 0.01  # a neighbour this much farther makes a pixel an edge
    edge_width_px: int = 1  # missing band beside each discontinuity
    grazing_deg: float = 78.0  # surfaces seen more obliquely return no depth
    dropout: float = 0.002  # share of valid pixels dropped at random

    def __post_init__(self) -> None:
        for key in ("baseline_m", "focal_px", "subpixel", "edge_jump_m"):
            if getattr(self, key) <= 0:
                raise ValueError(
                    f"sensor.rgbd.realsense.{key}={getattr(self, key)} must be > 0 (D435: "
                    "baseline_m=0.05, focal_px=447, subpixel=0.08, edge_jump_m=0.01)"
                )
        if self.edge_width_px < 0:
            raise ValueError(
                f"sensor.rgbd.realsense.edge_width_px={self.edge_width_px} must be >= 0 (0 = off)"
            )
        if not 0.0 < self.grazing_deg <= 90.0:
            raise ValueError(
                f"sensor.rgbd.realsense.grazing_deg={self.grazing_deg} must be in (0, 90] (90 = off)"
            )
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"sensor.rgbd.realsense.dropout={self.dropout} must be in [0, 1)")


class RealSenseDepthNoise:
    """Applies the RealSense-like noise model to exact rendered depth (0 = nothing rendered)."""

    def __init__(self, config: RealSenseNoiseConfig, intrinsics: Intrinsics, seed: int) -> None:
        self.config = config
        self.intrinsics = intrinsics
        self._rng = np.random.default_rng(seed)
        v, u = np.mgrid[0 : intrinsics.height, 0 : intrinsics.width].astype(np.float32)
        self._ray_x = ((u - intrinsics.cx) / intrinsics.fx).astype(np.float32)
        self._ray_y = ((v - intrinsics.cy) / intrinsics.fy).astype(np.float32)
        self._ray_sq = self._ray_x**2 + self._ray_y**2 + 1.0
        self._cos_sq = np.float32(np.cos(np.deg2rad(config.grazing_deg)) ** 2)

    def sigma(self, depth: np.ndarray) -> np.ndarray:
        """Depth standard deviation (metres) at depth z: z^2 * subpixel / (focal_px * baseline)."""
        c = self.config
        return depth * depth * (c.subpixel / (c.focal_px * c.baseline_m))

    def missing(self, depth: np.ndarray) -> np.ndarray:
        """Pixels with no stereo match: at discontinuities, at grazing angles, at random."""
        c = self.config
        valid = depth > 0
        # Background (0) counts as infinitely far, so an object's outline is an edge too.
        far = np.where(valid, depth, np.float32(1e3)).astype(np.float32)
        kernel = np.ones((3, 3), np.uint8)
        jump = (cv2.dilate(far, kernel) - far > c.edge_jump_m) | (
            far - cv2.erode(far, kernel) > c.edge_jump_m
        )
        if c.edge_width_px > 1:
            size = 2 * c.edge_width_px - 1
            jump = cv2.dilate(jump.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
        missing = valid & (jump | self._grazing(depth))
        if c.dropout > 0:
            missing |= valid & (self._rng.random(depth.shape) < c.dropout)
        return missing

    def _grazing(self, depth: np.ndarray) -> np.ndarray:
        """Pixels whose surface normal is more than grazing_deg from the viewing ray."""
        depth = depth.astype(np.float32, copy=False)
        px, py = self._ray_x * depth, self._ray_y * depth
        # Central differences along columns (u) and rows (v); their common factor of 2
        # scales the normal, not its direction.
        dxu, dxv = _derivatives(px)
        dyu, dyv = _derivatives(py)
        dzu, dzv = _derivatives(depth)
        nx = dyu * dzv - dzu * dyv
        ny = dzu * dxv - dxu * dzv
        nz = dxu * dyv - dyu * dxv
        # cos(angle) between the normal and the ray (x, y, 1), compared squared: no roots.
        dot = nx * self._ray_x + ny * self._ray_y + nz
        normal_sq = nx * nx + ny * ny + nz * nz
        return dot * dot < self._cos_sq * normal_sq * self._ray_sq

    def __call__(self, depth: np.ndarray) -> np.ndarray:
        """Noisy copy of `depth` (H, W) float32: Gaussian with sigma(z), missing pixels 0."""
        depth = np.asarray(depth, np.float32)
        if depth.shape != (self.intrinsics.height, self.intrinsics.width):
            raise ValueError(
                f"depth shape {depth.shape} does not match the intrinsics "
                f"({self.intrinsics.height}, {self.intrinsics.width})"
            )
        valid = depth > 0
        missing = self.missing(depth)
        noise = self._rng.standard_normal(depth.shape).astype(np.float32) * self.sigma(depth)
        noisy = np.where(valid, np.maximum(depth + noise, 1e-4), 0.0).astype(np.float32)
        noisy[missing] = 0.0
        return noisy


def _derivatives(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Twice the central difference of a float32 image along columns and along rows."""
    return (
        cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=1),
        cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=1),
    )
