"""What the mapper has seen: camera keyframes, every touch, and the space-carving record.

`MapMemory.add` stores one frame's object-frame points: a random subset of the camera's
(`camera_points_per_frame`) becomes a keyframe with the camera centre, each finger's
contact patch becomes a touch of exactly `tactile_points_per_touch` points with the
sensor axis and its label when the classifier's label is usable, and, with the space
prior on, the camera's rays carve free space and the kept points grow the hull.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import torch

from neuralfeels_sem.core.frame import Frame, TactileReading
from neuralfeels_sem.core.geometry import invert_pose, project, transform_points
from neuralfeels_sem.mapping.keyframes import KeyframeBuffer
from neuralfeels_sem.mapping.label_vote import LabelVote
from neuralfeels_sem.mapping.press_fusion import PressFusion
from neuralfeels_sem.mapping.sampling import subsample
from neuralfeels_sem.mapping.space_prior import SpaceCarvingPrior
from neuralfeels_sem.mapping.touch_memory import TouchBuffer
from neuralfeels_sem.perception.pointcloud import object_T_sensor, sensor_origin_and_axis
from neuralfeels_sem.perception.touch import TouchLabel

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig


class MapMemory:
    """Keyframes (windowed), touches (all replayed) and the space prior (None when off)."""

    def __init__(
        self,
        config: MapperConfig,
        bound: float,
        center: np.ndarray,
        generator: torch.Generator,
        device: torch.device,
    ) -> None:
        """`bound`, `center`: the field's cube (the space prior's grid covers it)."""
        self.camera_points_per_frame = config.camera_points_per_frame
        self.tactile_points_per_touch = config.tactile_points_per_touch
        self.truncation = float(config.truncation)
        self.hull_every = config.space_prior_hull_every
        self.generator = generator  # the mapper's: subsets are repeatable and resumable
        self.device = device
        self.keyframes = KeyframeBuffer(
            config.max_keyframes, config.window_recent, config.window_by_loss
        )
        self.touches = TouchBuffer(
            device, LabelVote.from_config(config), PressFusion.from_config(config)
        )
        self.space_prior = (
            SpaceCarvingPrior(
                float(bound), center, resolution=config.space_prior_resolution, seed=config.seed
            )
            if config.space_prior_points > 0
            else None
        )

    @property
    def has_data(self) -> bool:
        return len(self.keyframes) > 0 or self.touches.num_touches > 0

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(array, dtype=np.float32), device=self.device)

    def add(
        self,
        frame: Frame,
        points: dict[str, np.ndarray],
        every_pixel: np.ndarray | None,
        world_T_object: np.ndarray,
        touch_labels: Mapping[str, TouchLabel],
    ) -> tuple[int, int]:
        """Store one frame's points (PointExtractor.extract); (camera, tactile) points kept."""
        kept = {"camera": 0, "tactile": 0}
        self.touches.note_frame(frame.index)
        for source, pts in points.items():
            if source == "camera":
                kept["camera"] += self._add_camera(frame, pts, every_pixel, world_T_object)
            else:
                label = touch_labels.get(source)
                kept["tactile"] += self._add_touch(frame, source, pts, world_T_object, label)
        if self.space_prior is not None and self._hull_due(frame.index):
            self.space_prior.update_hull(frame.index)
        return kept["camera"], kept["tactile"]

    def _hull_due(self, frame_index: int) -> bool:
        """Rebuild the hull on the first frame mapped of each block of `hull_every` frame
        indices (offline: every hull_every-th frame; at realtime pace, where frames are
        skipped, still once a block), and while there is none."""
        built_at = self.space_prior.built_at
        return (
            not self.space_prior.ready
            or built_at is None
            or frame_index // self.hull_every != built_at // self.hull_every
        )

    def _add_camera(
        self, frame: Frame, pts: np.ndarray, every_pixel: np.ndarray | None, pose: np.ndarray
    ) -> int:
        keep = subsample(
            len(pts), self.camera_points_per_frame, self.generator, replace_if_short=False
        )
        kept = pts[keep.numpy()]
        origin, _ = sensor_origin_and_axis(frame.camera.world_T_camera, pose)
        self.keyframes.add(self._tensor(kept), self._tensor(origin), frame.index)
        if self.space_prior is not None:
            # Every pixel's ray, hand and background included, crosses free space.
            self.space_prior.carve(origin, every_pixel, self.truncation)
            self.space_prior.add_surface(kept)
        return len(keep)

    def _add_touch(
        self,
        frame: Frame,
        finger: str,
        pts: np.ndarray,
        pose: np.ndarray,
        label: TouchLabel | None,
    ) -> int:
        keep = subsample(
            len(pts), self.tactile_points_per_touch, self.generator, replace_if_short=True
        )
        kept = pts[keep.numpy()]
        _, axis = sensor_origin_and_axis(frame.tactile[finger].world_T_sensor, pose)
        if self.space_prior is not None:
            self.space_prior.add_surface(kept)
        labels, weights = touch_point_labels(frame.tactile[finger], kept, pose, label)
        read = label is not None and label.contact and label.probs is not None
        self.touches.add(
            self._tensor(kept),
            self._tensor(axis),
            torch.as_tensor(labels, dtype=torch.long, device=self.device),
            self._tensor(weights),
            finger=finger,
            frame_index=frame.index,
            probs=self._tensor(label.probs) if read else None,
            at_edge=read and label.at_edge,
        )
        return len(keep)

    def move_frame(self, frame_index: int, object_T_object: np.ndarray) -> int:
        """Re-place one frame's keyframes and touches after its pose was refined
        (pose_window.py); the space prior's coarse record stays. Items moved."""
        move = torch.as_tensor(np.asarray(object_T_object), dtype=torch.float32, device=self.device)
        rotation, shift = move[:3, :3], move[:3, 3]
        return self.keyframes.move_frame(frame_index, rotation, shift) + self.touches.move_frame(
            frame_index, rotation, shift
        )

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        return {
            "keyframes": self.keyframes.state_dict(),
            "touches": self.touches.state_dict(),
            "space_prior": self.space_prior.state_dict() if self.space_prior is not None else {},
        }

    def load_state_dict(self, state: dict) -> None:
        self.keyframes.load_state_dict(state["keyframes"], self.device)
        self.touches.load_state_dict(state["touches"])
        if self.space_prior is not None and state.get("space_prior"):
            self.space_prior.load_state_dict(state["space_prior"])


def touch_point_labels(
    reading: TactileReading,
    points: np.ndarray,
    world_T_object: np.ndarray,
    label: TouchLabel | None,
) -> tuple[np.ndarray, np.ndarray]:
    """(N,) label and (N,) weight of each object-frame contact point of one touch.

    With patch readings (`label.pixel_labels`) each point takes the label of the pixel it
    was seen at (the points are projected back into the sensor); otherwise every point
    takes the touch's label when it is usable, weighted by its confidence (times the
    label's `weight`), else -1.
    """
    n = len(points)
    if label is None or not label.contact:
        return np.full(n, -1), np.zeros(n)
    if label.has_pixel_labels:
        sensor_T_object = invert_pose(object_T_sensor(reading.world_T_sensor, world_T_object))
        uv = project(transform_points(sensor_T_object, points), reading.intrinsics)
        h, w = label.pixel_labels.shape
        col = np.clip(np.rint(uv[:, 0]).astype(np.int64), 0, w - 1)
        row = np.clip(np.rint(uv[:, 1]).astype(np.int64), 0, h - 1)
        return label.pixel_labels[row, col].astype(np.int64), label.pixel_confidence[row, col]
    if label.usable:
        return np.full(n, label.label), np.full(n, label.confidence * label.weight)
    return np.full(n, -1), np.zeros(n)
