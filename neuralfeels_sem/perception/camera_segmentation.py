"""The object's pixels in a camera frame without ground truth: workspace, hand, plane, cluster.

The same steps run on real, simulated and replayed frames (docs/perception.md):
1. workspace: keep pixels whose 3D point lies in a box given in the palm frame;
2. hand: render the hand's own model at the frame's measured joint angles from the camera
   and drop pixels on or behind it (within `hand_margin_m`, grown by `hand_dilation_px`);
   an object surface in front of a finger is nearer than the finger and survives;
3. plane: fit the dominant plane (RANSAC) and drop it when it holds a large share of the
   points, is wider than a held object and passes clear of every fingertip (a table, not
   the object's flat face);
4. cluster: split the rest at depth jumps into connected pixel clusters, keep those with
   a point within `fingertip_radius_m` of a fingertip (the nearest one at least) and the
   clusters within `cluster_merge_m` of a kept one in 3D.
A frame with no such cluster has no object mask (the object is out of view or hidden).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import cv2
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.core.geometry import invert_pose, transform_points
from neuralfeels_sem.perception.plane_fit import fit_plane_ransac

if TYPE_CHECKING:  # pyrender (behind the renderer) loads only when a camera frame is segmented
    from neuralfeels_sem.perception.hand_depth import HandDepthRenderer

log = logging.getLogger(__name__)


class HandModel(Protocol):
    """What segmentation needs of a hand: its palm pose, its joints and its link meshes.

    `link_meshes` is optional: a model without it (no meshes) skips the hand step.
    """

    world_T_palm: np.ndarray
    joint_limits: np.ndarray  # (J, 2)

    def link_meshes(self, q: np.ndarray) -> list[tuple[trimesh.Trimesh, np.ndarray]]: ...


@dataclass
class SegmentationConfig:
    """mapping.mapper.segmentation: camera segmentation without ground truth."""

    # Workspace box in the palm frame (x out of the palm face, y across, z along the
    # fingers), metres: the grasped object and the fingertips, not the table or the arm.
    workspace_min: list[float] = field(default_factory=lambda: [-0.01, -0.15, -0.06])
    workspace_max: list[float] = field(default_factory=lambda: [0.25, 0.15, 0.20])
    hand_margin_m: float = 0.005  # measured depth at most this much nearer is still the hand
    hand_dilation_px: int = 1  # the rendered hand grown by this many pixels (calibration slack)
    plane_inlier_m: float = 0.005
    plane_iterations: int = 100
    plane_min_share: float = 0.2  # of the remaining points, for a plane to be removed
    # A support is wider than anything held in the hand: both in-plane spreads of its
    # points (5th to 95th percentile) must reach this, or a flat face is not removed.
    plane_min_extent_m: float = 0.12
    plane_clearance_m: float = 0.02  # a plane nearer than this to a fingertip is the object
    cluster_gap_m: float = 0.01  # a depth jump this large between neighbours splits clusters
    min_cluster_px: int = 30
    cluster_merge_m: float = 0.02  # clusters this close (3D) to a kept one are the object too
    fingertip_radius_m: float = 0.04
    seed: int = 0  # RANSAC draws

    def __post_init__(self) -> None:
        if len(self.workspace_min) != 3 or len(self.workspace_max) != 3:
            raise ValueError(
                "mapping.mapper.segmentation.workspace_min/max must be [x, y, z] in the palm frame"
            )
        if any(lo >= hi for lo, hi in zip(self.workspace_min, self.workspace_max, strict=True)):
            raise ValueError(
                f"mapping.mapper.segmentation.workspace_min={self.workspace_min} must be below "
                f"workspace_max={self.workspace_max} on every axis"
            )
        positive = (
            "hand_margin_m", "plane_inlier_m", "plane_iterations", "cluster_gap_m",
            "min_cluster_px", "cluster_merge_m", "fingertip_radius_m", "plane_clearance_m", "plane_min_extent_m",
        )  # fmt: skip
        for key in positive:
            if getattr(self, key) <= 0:
                raise ValueError(
                    f"mapping.mapper.segmentation.{key}={getattr(self, key)} must be > 0"
                )
        if self.hand_dilation_px < 0:
            raise ValueError(
                f"mapping.mapper.segmentation.hand_dilation_px={self.hand_dilation_px} must be >= 0"
            )
        if not 0.0 < self.plane_min_share <= 1.0:
            raise ValueError(
                f"mapping.mapper.segmentation.plane_min_share={self.plane_min_share} must be in (0, 1]"
            )


@dataclass
class Segmentation:
    """One frame's result: the object mask (all False when `found` is False) and its cost."""

    mask: np.ndarray
    found: bool
    seconds: float


class CameraSegmenter:
    """Segments the grasped object in camera frames; see the module docstring for the steps.

    Args:
        config: the segmentation settings.
        hand: the hand's kinematic model (Sensor.hand_model()); None: no workspace crop
            and no hand removal (one warning), only plane removal and clustering.
    """

    def __init__(self, config: SegmentationConfig, hand: HandModel | None) -> None:
        self.config = config
        self.hand = hand
        self._renderer: HandDepthRenderer | None = None
        self._rng = np.random.default_rng(config.seed)
        self._has_meshes = hand is not None and callable(getattr(hand, "link_meshes", None))
        if hand is None:
            log.warning("camera segmentation has no hand model: no workspace crop, no hand removal")
        elif not self._has_meshes:
            log.warning(
                "hand model %s has no link meshes: camera segmentation skips hand removal",
                type(hand).__name__,
            )
        self._warned_no_joints = False

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __call__(
        self,
        reading: CameraReading,
        joint_positions: np.ndarray | None,
        fingertips: np.ndarray,
    ) -> Segmentation:
        """The object mask of `reading`; `fingertips` (K, 3) are world points (gel centres)."""
        start = time.perf_counter()
        depth = np.asarray(reading.depth, np.float32)
        mask = np.isfinite(depth) & (depth > 0)
        cam_points = _camera_frame_points(depth, reading)
        world = transform_points(reading.world_T_camera, cam_points.reshape(-1, 3))
        world = world.reshape(cam_points.shape)
        if self.hand is not None:
            mask &= self._in_workspace(world)
            mask &= ~self._hand_pixels(reading, depth, joint_positions)
        fingertips = np.asarray(fingertips, np.float64).reshape(-1, 3)
        if len(fingertips) == 0 and self.hand is not None:
            box_centre = 0.5 * (np.asarray(self.config.workspace_min) + self.config.workspace_max)
            fingertips = transform_points(self.hand.world_T_palm, box_centre[None])
        mask &= ~self._plane_pixels(world, mask, fingertips)
        mask = self._fingertip_clusters(depth, world, mask, fingertips)
        return Segmentation(mask=mask, found=bool(mask.any()), seconds=time.perf_counter() - start)

    def _in_workspace(self, world: np.ndarray) -> np.ndarray:
        palm = transform_points(invert_pose(self.hand.world_T_palm), world.reshape(-1, 3))
        inside = np.ones(len(palm), bool)
        # Axis by axis: numpy's reduction over a last axis of three is several times slower.
        for axis, (low, high) in enumerate(
            zip(self.config.workspace_min, self.config.workspace_max)
        ):
            inside &= (palm[:, axis] >= low) & (palm[:, axis] <= high)
        return inside.reshape(world.shape[:2])

    def _hand_pixels(
        self, reading: CameraReading, depth: np.ndarray, q: np.ndarray | None
    ) -> np.ndarray:
        """Pixels on or behind the rendered hand (all False when the hand cannot be rendered)."""
        if not self._has_meshes:
            return np.zeros(depth.shape, bool)
        if q is None:
            if not self._warned_no_joints:
                log.warning("frames carry no joint positions: camera segmentation skips the hand")
                self._warned_no_joints = True
            return np.zeros(depth.shape, bool)
        q = np.asarray(q, np.float64)
        joints = len(self.hand.joint_limits)
        if q.shape != (joints,):
            raise ValueError(
                f"joint_positions has shape {q.shape} but the hand model has {joints} joints: "
                "the sensor must report every joint of the hand it names"
            )
        if self._renderer is None or self._renderer.intrinsics != reading.intrinsics:
            self.close()
            from neuralfeels_sem.perception.hand_depth import HandDepthRenderer

            self._renderer = HandDepthRenderer(reading.intrinsics)
        hand = self._renderer.render(reading.world_T_camera, self.hand.link_meshes(q))
        hand = np.where(hand > 0, hand, np.float32(np.inf))
        size = 2 * self.config.hand_dilation_px + 1
        # The nearest hand surface within the dilation: a pixel beside a finger's outline
        # that is no nearer than that finger is the finger (or hidden behind it).
        nearest = cv2.erode(hand, np.ones((size, size), np.uint8))
        return np.isfinite(nearest) & (depth >= nearest - self.config.hand_margin_m)

    def _plane_pixels(
        self, world: np.ndarray, mask: np.ndarray, fingertips: np.ndarray
    ) -> np.ndarray:
        """Pixels of a dominant plane clear of the fingertips (a table), else all False."""
        c = self.config
        points = world[mask]
        none = np.zeros(mask.shape, bool)
        if len(points) < c.min_cluster_px:
            return none
        sample = points[self._rng.integers(0, len(points), size=min(len(points), 4000))]
        plane = fit_plane_ransac(sample, c.plane_inlier_m, c.plane_iterations, self._rng)
        if plane is None:
            return none
        normal, offset = plane
        on_plane = np.abs(world @ normal + offset) < c.plane_inlier_m
        share = (on_plane & mask).sum() / mask.sum()
        if share < c.plane_min_share:
            return none
        if len(fingertips) and np.abs(fingertips @ normal + offset).min() < c.plane_clearance_m:
            return none  # a flat face the fingers touch is the object's
        if _smaller_spread(world[on_plane & mask]) < c.plane_min_extent_m:
            return none
        return on_plane & mask

    def _fingertip_clusters(
        self, depth: np.ndarray, world: np.ndarray, mask: np.ndarray, fingertips: np.ndarray
    ) -> np.ndarray:
        """The clusters of `mask` near the fingertips (all False when there is none)."""
        c = self.config
        near = np.where(mask, depth, np.float32(np.inf))
        # The far side of a depth jump is a boundary: clusters meet only along smooth depth.
        nearest = cv2.erode(near, np.ones((3, 3), np.uint8))
        boundary = depth - nearest > c.cluster_gap_m
        count, labels, stats, _ = cv2.connectedComponentsWithStats(
            (mask & ~boundary).astype(np.uint8), connectivity=8
        )
        big = [i for i in range(1, count) if stats[i, cv2.CC_STAT_AREA] >= c.min_cluster_px]
        points = {i: world[labels == i] for i in big}
        distances = np.full(count, np.inf)
        for label in big if len(fingertips) else ():
            gaps = np.linalg.norm(points[label][:, None, :] - fingertips[None], axis=2)
            distances[label] = gaps.min()
        keep = np.zeros(count, bool)
        if np.isfinite(distances).any():
            keep = distances <= c.fingertip_radius_m
            keep[int(np.argmin(distances))] |= distances.min() <= 2 * c.fingertip_radius_m
        if keep.any():
            self._grow(keep, points)
        return keep[labels] & mask

    def _grow(self, keep: np.ndarray, points: dict[int, np.ndarray]) -> None:
        """Add the clusters within `cluster_merge_m` (3D) of a kept one, until none is.

        A part of the object that sticks out (an ear, a handle) meets the body at a depth
        jump in the image, so it is a cluster of its own, yet touches the body in 3D.
        """
        while True:
            kept = np.concatenate([points[i] for i in points if keep[i]])
            tree = cKDTree(kept[:: max(1, len(kept) // 4000)])
            added = [
                i
                for i in points
                if not keep[i]
                and np.isfinite(
                    tree.query(points[i], distance_upper_bound=self.config.cluster_merge_m)[0]
                ).any()
            ]
            if not added:
                return
            keep[added] = True


def _smaller_spread(points: np.ndarray) -> float:
    """The smaller 5th-95th percentile range of planar points along their two main axes."""
    centred = points - points.mean(axis=0)
    axes = np.linalg.svd(centred[:: max(1, len(centred) // 2000)], full_matrices=False)[2][:2]
    along = centred @ axes.T
    spread = np.percentile(along, 95, axis=0) - np.percentile(along, 5, axis=0)
    return float(spread.min())


def _camera_frame_points(depth: np.ndarray, reading: CameraReading) -> np.ndarray:
    """(H, W, 3) camera-frame point of every pixel (zeros where depth is 0)."""
    k = reading.intrinsics
    v, u = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]].astype(np.float32)
    depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    return np.stack([(u - k.cx) / k.fx * depth, (v - k.cy) / k.fy * depth, depth], axis=-1)
