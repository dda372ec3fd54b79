"""Where the object pose used for mapping comes from (`mapping.pose`).

`gt` takes the frame's pose (the simulator's, or markers on hardware): the paper's
setting. `track` estimates it per frame by aligning the frame's camera and touch points
to the field being learned (NeuralFeels' SLAM loop: track, then map with the tracked
pose); `track_known_shape` aligns them to the ground-truth mesh (NeuralFeels' pose
tracking mode). Both also compare the frame's colours with earlier camera views
(colour_keyframes.py), a motion cue that does not depend on the map. Every source also reports how its pose relates to the ground truth, so
a run in tracked mode is scored the way a user without ground truth would see it.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Literal, Protocol, get_args

import numpy as np
import torch

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import invert_pose, orthonormalize_pose
from neuralfeels_sem.mapping.colour_keyframes import ColourKeyframes
from neuralfeels_sem.mapping.fit_check import relative_failure
from neuralfeels_sem.mapping.pose_error import PoseErrorLog, write_pose_error_plot
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig
from neuralfeels_sem.mapping.pose_window import PoseWindow
from neuralfeels_sem.mapping.relocalise import relocalise
from neuralfeels_sem.mapping.se3 import constant_velocity
from neuralfeels_sem.mapping.track_counts import TrackingCounts

log = logging.getLogger(__name__)

PoseMode = Literal["gt", "track", "track_known_shape"]  # mapping.pose
POSE_SOURCES = get_args(PoseMode)
TRACKED = ("track", "track_known_shape")
WARM_UP = "no surface learned yet"  # frames of `track` kept (and mapped) before the field has one


def resolve_pose_source(pose: str) -> str:
    """Check `mapping.pose`: one of POSE_SOURCES."""
    if pose not in POSE_SOURCES:
        raise ConfigError(f"mapping.pose={pose!r} is unknown; use one of {POSE_SOURCES}")
    return pose


class MapView(Protocol):
    """What a pose source may read from the mapper (OnlineMapper provides it)."""

    def frame_points(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        """The frame's surface points per source, mapped by `world_T_object`'s inverse."""

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        """The learned signed distance (metres) at object-frame points (N, 3)."""

    @property
    def has_surface(self) -> bool:
        """Whether the field has been trained on any data yet."""


class PoseSource:
    """Pose per frame for the mapper; `gt` behaviour (the frame's own pose)."""

    name = "gt"
    fuse = True  # whether the mapper should fuse the last estimated frame into the map
    reads_frame_pose = True  # a frame's pose is its own (a frame not estimated has one too)

    def estimate(self, frame: Frame, mapper: MapView | None) -> np.ndarray:
        """world_T_object to map this frame with."""
        self.last_estimate = frame.world_T_object
        self.last_frame = frame
        return frame.world_T_object

    def field_T_gt_object(self) -> np.ndarray:
        """Maps ground-truth object-frame points into the field's frame at the last frame.

        Identity when the mapping pose is the ground truth; with a tracked pose it carries
        the tracking error, so matching and shape scores include it.
        """
        frame = getattr(self, "last_frame", None)
        if frame is None or frame.gt_world_T_object is None:
            return np.eye(4)
        return invert_pose(self.last_estimate) @ frame.gt_world_T_object

    def metrics(self) -> dict:
        """Pose-error figures for metrics.json (none for the ground-truth pose)."""
        return {}

    def notes(self) -> list[str]:
        """Lines for metrics.json `notes` (none for the ground-truth pose)."""
        return []

    def write_pictures(self, out_dir, dpi: int) -> None:
        """Pose-error plot (pose_error.png) for tracking sources; nothing for `gt`."""

    def state(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


class TrackedPose(PoseSource):
    """Tracks the object pose per frame with a PoseTracker (see the module docstring).

    The first frame's own pose (frame.world_T_object) is the origin of the map; after it
    the frame's pose is never read. Until the mapper has trained on a frame (`track`)
    there is no surface to align to, so the constant-velocity prediction is kept.
    Pose error (the "average 3D error": mean distance between ground-truth surface samples
    placed by the tracked and by the true pose) is recorded wherever the frame has a
    ground-truth pose.
    """

    reads_frame_pose = False  # after the first frame, only estimates

    def __init__(
        self,
        mode: str,
        obj=None,
        tracker: PoseTracker | None = None,
        error_samples: int = 2000,
        known_shape_resolution: int = 96,
        seed: int = 0,
    ) -> None:
        if mode not in TRACKED:
            raise ValueError(f"mode={mode!r} must be one of {TRACKED}")
        if mode == "track_known_shape" and obj is None:
            raise ValueError("track_known_shape needs the object (its ground-truth mesh)")
        if error_samples < 1:
            raise ValueError(f"error_samples={error_samples} must be >= 1")
        self.name = mode
        self.obj = obj
        self.tracker = tracker or PoseTracker(
            TrackerConfig(rotation_scale=obj.bounds_radius, seed=seed)
            if obj is not None
            else TrackerConfig(seed=seed)
        )
        self.error_samples = error_samples
        self.known_shape_resolution = known_shape_resolution
        self.seed = seed
        self._known_sdf = None
        self.history: list[np.ndarray] = []  # the last two estimates (motion prior)
        self.errors = PoseErrorLog(self._surface_points)
        self.counts = TrackingCounts()
        self.colour = ColourKeyframes(self.tracker.colour, seed)
        self._view = None  # the current frame's colour view
        self._terms: list = []  # the current frame's colour rows
        self.window = PoseWindow(self.tracker.window, self.tracker)  # off unless configured

    # ---------------------------------------------------------------- tracking
    def _sdf_fn(self, mapper: MapView):
        if self.name == "track":
            return mapper.sdf
        if self._known_sdf is None:
            from neuralfeels_sem.mapping.known_shape import GridSdf

            self._known_sdf = GridSdf.of_mesh(self.obj.mesh, self.known_shape_resolution)
        return self._known_sdf

    def _keep(self, reason: str) -> None:
        self.counts.kept[reason] = self.counts.kept.get(reason, 0) + 1

    def estimate(self, frame: Frame, mapper: MapView) -> np.ndarray:
        points = self._world_points(frame, mapper) if self.history else None
        tracked, self.fuse = False, True
        if not self.history:
            pose, tracked = np.asarray(frame.world_T_object, dtype=np.float64).copy(), True
        elif self.name == "track" and not mapper.has_surface:
            pose = constant_velocity(self.history)
            self._keep(WARM_UP)
        else:
            pose, tracked = self._track(frame, mapper, points)
            pose = self._refine(frame.index, pose, tracked, points, mapper)
            # Only a tracked pose writes to the map (the warm-up frames above build it): a
            # frame mapped with a pose that fits badly teaches the field to agree with it.
            self.fuse = tracked
        pose = orthonormalize_pose(pose)
        if points is None and self.colour.enabled:
            self._world_points(frame, mapper)  # the first frame: its colour view
        self.colour.add(self._view, pose, tracked)
        self.history = (self.history + [pose])[-2:]
        self.last_estimate = pose
        self.last_frame = frame
        if frame.gt_world_T_object is not None:
            self.errors.add(frame.index, frame.time_s, pose, frame.gt_world_T_object)
        return pose

    def _world_points(self, frame: Frame, mapper: MapView) -> dict[str, np.ndarray]:
        """The frame's points per source in the world frame; remembers its colour view."""
        points = mapper.frame_points(frame, np.eye(4))
        self._view = self.colour.view(frame, points.get("camera"))
        return points

    def _track(
        self, frame: Frame, mapper: MapView, points: dict[str, np.ndarray]
    ) -> tuple[np.ndarray, bool]:
        """The frame's pose and whether it was tracked (passed every check).

        A solve from the constant-velocity prediction that does not fit (fit_check.py:
        the absolute checks, and the drop against the recent tracked frames) or diverges
        is retried from the last pose (no motion assumed): the prediction carries the
        last frame's motion, and a wrong one can start the solve in a wrong basin. If
        that fails too the frame is re-localised (relocalise.py). Too few points are not
        retried: no start can fix them. Colour terms against earlier views
        (colour_keyframes.py) join every solve.

        A frame no solve fits is not tracked (counted); it takes the solve that failed
        the relative check alone with the highest inlier share, if any (it still fits the
        frame better than a blind extrapolation), else the prediction.
        """
        predicted = constant_velocity(self.history)
        tensors = {source: torch.as_tensor(p) for source, p in points.items()}
        sdf_fn = self._sdf_fn(mapper)
        start = time.perf_counter()
        terms = self._terms = self.colour.terms(self._view, predicted)
        self.counts.colourless_frames += int(self.colour.enabled and not terms)
        closest: tuple[np.ndarray, dict] | None = None  # best solve failing the drop only

        def solve(init: np.ndarray) -> tuple[np.ndarray, dict]:
            nonlocal closest
            pose, info = self._solve(tensors, sdf_fn, init, predicted, terms)
            if info.get("relative") and (
                closest is None or info["inlier_share"] > closest[1]["inlier_share"]
            ):
                closest = (pose, info)
            return pose, info

        pose, info = solve(predicted)
        retried = relocalised = False
        if _retry(info):
            retried = True
            pose, info = solve(self.history[-1])
        if _retry(info) and self.tracker.relocalise_deg > 0:
            found = relocalise(solve, self.history[-1], points, self.tracker.relocalise_deg)
            if found is not None:
                (pose, info), relocalised = found, True
        self.counts.track_seconds += time.perf_counter() - start
        if info["skipped"] and closest is not None:
            pose, info = closest
        tracked = self._record(frame.index, info, retried, relocalised)
        return (pose if tracked or info.get("relative") else predicted), tracked

    def _refine(self, index: int, pose: np.ndarray, tracked: bool, points, mapper) -> np.ndarray:
        """The frame's pose refined with the last tracked frames' (pose_window.py); earlier
        frames whose pose moved are re-placed in the map. A frame not tracked breaks the
        motion chain: the window starts again."""
        if not (self.window.enabled and tracked):
            self.window.reset()
            return pose
        start = time.perf_counter()
        pose, moves = self.window.refine(index, pose, points, self._sdf_fn(mapper), self._terms)
        for moved, object_T_object in moves.items():
            mapper.move_frame(moved, object_T_object)
            self.colour.repose(moved, object_T_object)
        # The motion prior's last pose is the previous frame's (not index - 1: frames skip).
        if self.history and self.last_frame.index in moves:
            self.history[-1] = self.history[-1] @ invert_pose(moves[self.last_frame.index])
        self.counts.track_seconds += time.perf_counter() - start
        return pose

    def _record(self, index: int, info: dict, retried: bool, relocalised: bool) -> bool:
        """Count the frame's outcome (its final solve's `info`); whether it was tracked."""
        if "inlier_share" in info:
            self.counts.fit_curve.append(
                [int(index), float(info["inlier_share"]), float(info["conditioning"])]
            )
        if info["skipped"]:
            log.warning("pose tracking: frame %d not tracked: %s", index, info["skipped"])
            self._keep(info["skipped"].split(" (")[0])
            self.counts.kept_in_a_row += 1
            return False
        self.counts.kept_in_a_row = 0
        self.counts.tracked_frames += 1
        self.counts.reinitialised_frames += int(retried and not relocalised)
        self.counts.relocalised_frames += int(relocalised)
        self.counts.degenerate_frames += int(info["degenerate"])
        self.counts.recent_shares = (self.counts.recent_shares + [float(info["inlier_share"])])[
            -self.tracker.fit_window :
        ]
        return True

    def _solve(self, tensors, sdf_fn, init: np.ndarray, predicted: np.ndarray, terms):
        """One tracker solve from `init`, failed also when it fits clearly worse than the
        recent tracked frames did (fit_check.relative_failure; info["relative"] marks it).
        After fit_window frames in a row were not tracked that reference is stale (the
        view has changed): the absolute checks alone decide until one is tracked again."""
        pose, info = self.tracker.track(tensors, sdf_fn, init, predicted, terms)
        stale = self.counts.kept_in_a_row >= self.tracker.fit_window
        if not info["skipped"] and not stale:
            info["skipped"] = relative_failure(
                info["inlier_share"], self.counts.recent_shares, self.tracker.max_inlier_drop
            )
            info["relative"] = info["skipped"] is not None
        return pose, info

    def _surface_points(self) -> np.ndarray:
        if self.obj is None:
            raise ValueError("the pose error needs the object's mesh (pass obj)")
        return self.obj.sample_surface(self.error_samples, seed=self.seed)[0]

    # ---------------------------------------------------------------- outputs
    @property
    def frames_not_tracked(self) -> int:
        """Frames after the first that were not tracked, for any reason."""
        return sum(self.counts.kept.values())

    @property
    def frames_not_mapped(self) -> int:
        """Frames not tracked that the mapper did not fuse: all but the warm-up frames."""
        return self.frames_not_tracked - self.counts.kept.get(WARM_UP, 0)

    def notes(self) -> list[str]:
        """One line on the frames that were not tracked (none when every frame was)."""
        if not self.frames_not_tracked:
            return []
        reasons = ", ".join(f"{n} {why}" for why, n in sorted(self.counts.kept.items()))
        return [
            f"pose: {self.frames_not_tracked} frames not tracked ({reasons}), "
            f"{self.frames_not_mapped} of them not mapped; {self.counts.tracked_frames} tracked"
        ]

    def metrics(self) -> dict:
        attempts = self.counts.tracked_frames + sum(
            n for why, n in self.counts.kept.items() if why != WARM_UP
        )
        out: dict = {
            "pose_frames_tracked": self.counts.tracked_frames,
            "pose_frames_kept": dict(self.counts.kept),
            "pose_frames_not_tracked": self.frames_not_tracked,
            "pose_frames_reinitialised": self.counts.reinitialised_frames,
            "pose_frames_relocalised": self.counts.relocalised_frames,
            "pose_frames_not_mapped": self.frames_not_mapped,
            "pose_frames_degenerate": self.counts.degenerate_frames,
            "pose_frames_without_colour": self.counts.colourless_frames,
            "pose_colour_keyframes": len(self.colour.keyframes),
            "pose_notes": self.notes(),
            # every solve's time, including the ones rejected, over the frames that tried
            "pose_track_s_per_frame": self.counts.track_seconds / max(attempts, 1),
            "pose_fit_curve": [list(row) for row in self.counts.fit_curve],
        }
        out.update(self.errors.metrics())
        out.update(self.window.metrics() if self.window.enabled else {})
        return out

    def write_pictures(self, out_dir, dpi: int) -> None:
        if self.errors.curve:
            path = Path(out_dir) / "pose_error.png"
            write_pose_error_plot(self.errors.curve, self.name, path, dpi)

    # ---------------------------------------------------------------- resume
    def state(self) -> dict:
        return {
            "history": [p.tolist() for p in self.history],
            **self.errors.state(),
            **self.counts.state(),
            "colour": self.colour.state(),
            "window": self.window.state(),
            "generator": self.tracker.generator.get_state(),
        }

    def load_state(self, state: dict) -> None:
        self.history = [np.asarray(p, dtype=np.float64) for p in state.get("history", [])]
        self.errors.load_state(state)
        self.counts.load_state(state)
        self.colour.load_state(state.get("colour", {}))
        self.window.load_state(state.get("window", {}))
        if state.get("generator") is not None:
            self.tracker.generator.set_state(state["generator"])
        if self.history:
            self.last_estimate = self.history[-1]


def _retry(info: dict) -> bool:
    """Whether a failed solve is worth another start (too few points: none can fix it)."""
    return bool(info["skipped"]) and not info["skipped"].startswith("too few points")


def build_pose_source(pose: str, obj=None, tracker: TrackerConfig | None = None) -> PoseSource:
    """The pose source named by `mapping.pose`; a PoseTracker (from `tracker`, else one
    scaled to the object) is built only for the modes that track."""
    resolve_pose_source(pose)
    if pose == "gt":
        return PoseSource()
    if pose == "track_known_shape" and obj is None:
        raise ConfigError(
            "mapping.pose=track_known_shape needs a ground-truth object mesh; use mapping.pose=track"
        )
    return TrackedPose(pose, obj, PoseTracker(tracker) if tracker is not None else None)
