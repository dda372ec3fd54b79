"""Earlier camera views a tracked frame is checked against for colour (colour_views.py).

Two kinds of reference: the previous frame (the largest overlap: visual odometry), and
keyframes, views kept whenever the object has turned more than `keyframe_angle_deg` from
every kept one. A frame is also compared with the keyframes nearest in orientation (up to
`keyframe_max_angle_deg` away): when the object comes back to an orientation it showed
before, the frame is tied to the view taken then, so drift collected since does not stay
(a loop closure on the current pose). A keyframe's pose is the one its frame is mapped
with: fixed once kept, unless the pose window (pose_window.py) refines that frame and
re-places its points in the map, when `repose` moves the view with them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.mapping.colour_views import ColourView, colour_residuals, visible_in
from neuralfeels_sem.mapping.residual_terms import ResidualTerm


@dataclass
class ColourConfig:
    """`mapping.tracker.colour`: colour consistency with earlier views (docs/pose.md).

    weight: total weight of each reference's colour rows relative to the camera SDF rows
        (0 switches colour off).
    scale_m: metres per unit of chromaticity, so the tracker's robust loss (robust_scale)
        applies to colour rows as to SDF rows.
    blur_px: Gaussian blur of the colour features (pixels): widens the basin beyond the
        aliased patch borders.
    erode_px: pixels a reference's object mask is shrunk by (mixed silhouette pixels).
    max_depth_gap_m: a pixel whose point lands in a reference this much in front of or
        behind what the reference measured there is hidden in it (self-occlusion, a finger).
    max_pixels: pixels per reference (random subset).
    min_pixels: a reference that sees fewer of the frame's pixels is not used.
    keyframe_angle_deg: keep a view as a keyframe when it turned this much from every kept one.
    keyframe_refs: keyframes compared with each frame (besides the previous frame).
    keyframe_max_angle_deg: farthest keyframe (in orientation) a frame is compared with.
    """

    weight: float = 30.0  # colour rows outweigh the SDF's: they see the turn it cannot
    scale_m: float = 0.01
    blur_px: float = 1.0
    erode_px: int = 1
    max_depth_gap_m: float = 0.004
    max_pixels: int = 1500
    min_pixels: int = 100
    keyframe_angle_deg: float = 10.0
    keyframe_refs: int = 1
    keyframe_max_angle_deg: float = 30.0

    def __post_init__(self) -> None:
        for name in ("scale_m", "max_depth_gap_m", "keyframe_angle_deg", "keyframe_max_angle_deg"):
            if not getattr(self, name) > 0:
                raise ValueError(f"mapping.tracker.colour.{name}={getattr(self, name)} must be > 0")
        for name in ("weight", "blur_px", "erode_px", "keyframe_refs"):
            if not getattr(self, name) >= 0:
                raise ValueError(
                    f"mapping.tracker.colour.{name}={getattr(self, name)} must be >= 0"
                )
        if self.max_pixels < 1 or not 1 <= self.min_pixels <= self.max_pixels:
            raise ValueError(
                f"mapping.tracker.colour needs 1 <= min_pixels ({self.min_pixels}) "
                f"<= max_pixels ({self.max_pixels})"
            )

    @classmethod
    def copy_of(cls, given: ColourConfig) -> ColourConfig:
        """A plain, checked copy of `given` (a config node read setting by setting)."""
        return cls(**{f.name: getattr(given, f.name) for f in fields(cls)})


def turned_deg(a_world_T_object: np.ndarray, b_world_T_object: np.ndarray) -> float:
    """Angle (degrees) of the rotation between two object orientations."""
    rot = a_world_T_object[:3, :3].T @ b_world_T_object[:3, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0))))


class ColourKeyframes:
    """The previous view and the keyframes, and the colour terms of a new frame."""

    def __init__(self, config: ColourConfig, seed: int = 0) -> None:
        self.config = config
        self.previous: ColourView | None = None
        self.keyframes: list[ColourView] = []
        self.generator = torch.Generator().manual_seed(int(seed))
        self.last_rows: dict[str, int] = {}  # pixels per reference used by the last frame

    @property
    def enabled(self) -> bool:
        return self.config.weight > 0

    def view(self, frame: Frame, camera_world: np.ndarray | None) -> ColourView | None:
        """The frame's object pixels as a view (None: colour off, or no camera points)."""
        if not self.enabled or frame.camera is None or camera_world is None:
            return None
        if len(camera_world) < self.config.min_pixels:
            return None
        c = self.config
        return ColourView.of(frame.index, frame.camera, camera_world, c.blur_px, c.erode_px)

    def references(self, predicted: np.ndarray) -> list[ColourView]:
        """The previous view and the keyframes nearest to `predicted` in orientation."""
        refs = [self.previous] if self.previous is not None else []
        ranked = sorted(
            (turned_deg(k.world_T_object, predicted), i) for i, k in enumerate(self.keyframes)
        )
        chosen = [
            self.keyframes[i]
            for angle, i in ranked
            if angle <= self.config.keyframe_max_angle_deg
            and (self.previous is None or self.keyframes[i].index != self.previous.index)
        ]
        return refs + chosen[: self.config.keyframe_refs]

    def terms(self, view: ColourView | None, predicted: np.ndarray) -> list[ResidualTerm]:
        """One colour term per reference that sees enough of `view`'s pixels, placed on the
        object by `predicted` (the visibility is decided there, once per frame)."""
        self.last_rows = {}
        if view is None:
            return []
        q = view.points_world @ invert_pose(predicted)[:3, :3].T + invert_pose(predicted)[:3, 3]
        out = []
        for ref in self.references(predicted):
            keep = np.flatnonzero(visible_in(ref, q, self.config.max_depth_gap_m))
            if len(keep) < self.config.min_pixels:
                continue
            if len(keep) > self.config.max_pixels:
                pick = torch.randperm(len(keep), generator=self.generator)[: self.config.max_pixels]
                keep = np.sort(keep[pick.numpy()])
            channels = view.colours.shape[1]
            rows = np.repeat(view.points_world[keep], channels, axis=0)
            fn = colour_residuals(ref, view.colours[keep], self.config.scale_m)
            kind = "previous" if ref is self.previous else "keyframe"
            self.last_rows[kind] = self.last_rows.get(kind, 0) + len(keep)
            out.append(ResidualTerm(rows, fn, self.config.weight, f"colour vs frame {ref.index}"))
        return out

    def add(self, view: ColourView | None, world_T_object: np.ndarray, tracked: bool) -> None:
        """Remember the frame's view with the pose it is mapped with. Only a tracked frame
        (or the first) may become a keyframe: a kept prediction is a guess."""
        if view is None:
            return
        view.world_T_object = np.asarray(world_T_object, np.float64).copy()
        self.previous = view.as_reference()
        far = all(
            turned_deg(k.world_T_object, view.world_T_object) > self.config.keyframe_angle_deg
            for k in self.keyframes
        )
        if far and (tracked or not self.keyframes):
            self.keyframes.append(view)

    def repose(self, index: int, object_T_object: np.ndarray) -> None:
        """Frame `index` was re-placed in the map by `object_T_object` (its object-frame
        points x -> object_T_object x): its view's pose follows."""
        for view in {id(v): v for v in (self.previous, *self.keyframes) if v}.values():
            if view.index == index:
                view.world_T_object = view.world_T_object @ invert_pose(object_T_object)

    def state(self) -> dict:
        """The previous view, the keyframes and the pixel sampler's state (for resume)."""
        keyframe_ids = {id(k) for k in self.keyframes}
        previous = self.previous
        return {
            "keyframes": [k.state() for k in self.keyframes],
            # the previous view is usually the newest keyframe: stored once
            "previous": None
            if previous is None or id(previous) in keyframe_ids
            else previous.state(),
            "previous_index": None if previous is None else int(previous.index),
            "generator": self.generator.get_state(),
        }

    def load_state(self, state: dict) -> None:
        self.keyframes = [ColourView.from_state(k) for k in state.get("keyframes", [])]
        self.previous = None
        if state.get("previous") is not None:
            self.previous = ColourView.from_state(state["previous"])
        elif state.get("previous_index") is not None:
            by_index = {k.index: k for k in self.keyframes}
            self.previous = by_index.get(int(state["previous_index"]))
        if state.get("generator") is not None:
            self.generator.set_state(state["generator"])
