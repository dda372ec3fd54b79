"""Which way to turn the object next (sensor.planner.turn=advice): the turn that brings the
most touch score to where the fingers press.

The gait turns the object about one axis and then another on a fixed schedule, whatever
the map already knows. With `turn=advice` the active policy chooses instead. The touches
the contact sampler screens (the surface points a finger could press at that moment) are
kept in the world frame as the fingers' reach. Every `turn_check_s` the candidate motions
are compared over the next `turn_horizon_s`: the advice's surface samples are carried
along each (steady poses, every `STEP_S`), a sample counts as brought to the fingers when
it passes within `turn_reach_m` of a reach point, and the motion's gain is the summed
touch score of the samples it brings, each once. With `facing_deg` a sample counts only
where its outward normal, carried along too, lies within that angle of the surface normal
the finger met at the reach point: a sample that passes the place facing elsewhere meets
the gel with its edge, or not at all. With `offered_weight` below 1, a sample within
`turn_reach_m` of a place the fingers could already have pressed (the screened touches so
far, object frame) counts that share of its score: it has passed the fingers and was not
chosen, and a turn that only brings it back (the reverse of the one just made) gains
little. The candidates are the plan (the turn the object is in, with the gait's
alternation ahead) and a turn about each of the planner's `axes`, either way round; a turn
replaces the plan only when its gain exceeds the plan's by the factor `turn_gain`, so that
a near tie keeps the gait's motion. With `turn=advance` the rig offers one candidate: the
axis of the gait's next stretch, begun now (the alternation moved forward; it never
reverses a turn or picks an axis of its own).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.spatial import cKDTree

STEP_S = 0.25  # the sweep is followed at this spacing (7.5 degrees at 30 deg/s)
REACH_MEMORY = 1024  # reach points kept (about 6 s of screened touches)
OFFERED_MEMORY = 16384  # object-frame places offered to the fingers (a 30 s run's screening)
NEAREST_REACH = 8  # reach points within reach_m compared by facing, nearest first


class Reach:
    """Where the fingers could press (world): (R, 3) points and, when known, the outward
    surface normal met at each; `facing_cos` the cosine a brought sample's normal must reach
    against it (None: any facing)."""

    def __init__(
        self,
        points: np.ndarray,
        normals: np.ndarray | None = None,
        facing_cos: float | None = None,
    ) -> None:
        self.points = np.asarray(points, np.float64).reshape(-1, 3)
        self.normals, self.facing_cos = normals, facing_cos
        self.tree = cKDTree(self.points)


def sweep_gain(
    surface: np.ndarray,
    scores: np.ndarray,
    poses: np.ndarray,
    reach: Reach,
    reach_m: float,
    normals: np.ndarray | None = None,
) -> float:
    """Summed score of the object-frame surface samples that pass within reach_m of a reach
    point (world) at any of the (K, 4, 4) world_T_object poses, each sample counted once.
    With the samples' `normals` (object frame) and a reach that has normals and a facing
    bound, a sample counts only where it faces as the surface met at that reach point."""
    facing = normals is not None and reach.normals is not None and reach.facing_cos is not None
    k = min(NEAREST_REACH, len(reach.points)) if facing else 1
    brought = np.zeros(len(surface), bool)
    for pose in poses:
        world = surface @ pose[:3, :3].T + pose[:3, 3]
        dist, near = reach.tree.query(world, k=k, distance_upper_bound=reach_m)
        if not facing:
            brought |= np.isfinite(dist)
            continue
        dist, near = dist.reshape(len(world), k), near.reshape(len(world), k)
        found = np.isfinite(dist)
        met = reach.normals[np.where(found, near, 0)]  # (S, k, 3)
        cos = np.einsum("skc,sc->sk", met, normals @ pose[:3, :3].T)
        brought |= (found & (cos >= reach.facing_cos)).any(axis=1)
    return float(scores[brought].sum())


class TurnChooser:
    """Keeps the fingers' reach and compares candidate turns (numpy only).

    Args:
        check_s: seconds between comparisons.
        horizon_s: how far ahead each motion is followed.
        gain: the factor by which a turn's gain must exceed the plan's to replace it.
        reach_m: how near a reach point a surface sample must pass to count as brought.
        axes: unit world axes a turn may be about (each either way round).
        facing_deg: how far a brought sample's normal may turn from the normal met at the
            reach point (None: any facing).
        offered_weight: the share of its score a sample keeps once the fingers could have
            pressed it (1: all of it).
    """

    def __init__(
        self,
        check_s: float,
        horizon_s: float,
        gain: float,
        reach_m: float,
        axes: np.ndarray,
        facing_deg: float | None = None,
        offered_weight: float = 1.0,
    ) -> None:
        self.check_s, self.gain, self.reach_m = float(check_s), float(gain), float(reach_m)
        self.offered_weight = float(offered_weight)
        self.offered: deque = deque(maxlen=OFFERED_MEMORY)  # object frame
        self.facing_cos = None if facing_deg is None else float(np.cos(np.deg2rad(facing_deg)))
        self.ahead = np.arange(1, int(round(horizon_s / STEP_S)) + 1) * STEP_S
        axes = np.asarray(axes, np.float64).reshape(-1, 3)
        axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        self.candidates = np.concatenate([axes, -axes])
        self.reach: deque = deque(maxlen=REACH_MEMORY)
        self.reach_normals: deque = deque(maxlen=REACH_MEMORY)  # NaN rows where unknown
        self.last_check_s = -np.inf
        # (time, plan's gain, best turn's gain, chosen axis or None) per comparison
        self.log: list[tuple[float, float, float, list[float] | None]] = []

    def note_reach(
        self,
        world_points: np.ndarray,
        world_normals: np.ndarray | None = None,
        object_points: np.ndarray | None = None,
    ) -> None:
        """Add the world-frame points a finger could press at one touch-down (and the
        outward surface normals there, world frame; and the same places in the object
        frame, for `offered_weight`)."""
        if object_points is not None and self.offered_weight < 1.0:  # kept only if read
            self.offered.extend(np.asarray(object_points, np.float64).reshape(-1, 3))
        points = np.asarray(world_points, np.float64).reshape(-1, 3)
        normals = (
            np.full_like(points, np.nan)
            if world_normals is None
            else np.asarray(world_normals, np.float64).reshape(-1, 3)
        )
        if len(normals) != len(points):
            raise ValueError(f"{len(points)} reach points but {len(normals)} normals")
        self.reach.extend(points)
        self.reach_normals.extend(normals)

    def due(self, t: float) -> bool:
        return bool(self.reach) and t - self.last_check_s >= self.check_s

    def choose(
        self,
        t: float,
        surface: np.ndarray,
        scores: np.ndarray,
        plan: np.ndarray,
        turns: list[np.ndarray],
        normals: np.ndarray | None = None,
        axes: np.ndarray | None = None,
    ) -> np.ndarray | None:
        """The axis to turn about from t (a row of `axes`), or None to keep the plan.

        plan: (K, 4, 4) poses at t + ahead; turns: one such array per candidate axis;
        normals: the surface samples' outward normals (object frame), for `facing_deg`;
        axes: the candidate axes compared this time (None: `candidates`).
        """
        axes = self.candidates if axes is None else np.asarray(axes, np.float64).reshape(-1, 3)
        if len(turns) != len(axes):
            raise ValueError(f"{len(turns)} turns for {len(axes)} candidate axes")
        self.last_check_s = float(t)
        reach = Reach(np.asarray(self.reach), self._reach_normals(), self.facing_cos)
        scores = self._discount_offered(surface, scores)
        kept = sweep_gain(surface, scores, plan, reach, self.reach_m, normals)
        gains = [
            sweep_gain(surface, scores, poses, reach, self.reach_m, normals) for poses in turns
        ]
        best = int(np.argmax(gains))
        chosen = axes[best] if gains[best] > self.gain * kept else None
        self.log.append((float(t), kept, gains[best], None if chosen is None else chosen.tolist()))
        return chosen

    def _reach_normals(self) -> np.ndarray | None:
        """The reach points' normals when the facing bound compares them (every one known)."""
        if self.facing_cos is None:
            return None
        met = np.asarray(self.reach_normals)
        return None if np.isnan(met).any() else met

    def _discount_offered(self, surface: np.ndarray, scores: np.ndarray) -> np.ndarray:
        """Scores with `offered_weight` applied where a sample lies within reach_m of a
        place already offered to the fingers (object frame)."""
        if self.offered_weight >= 1.0 or not self.offered:
            return scores
        dist, _ = cKDTree(np.asarray(self.offered)).query(
            surface, distance_upper_bound=self.reach_m
        )
        return np.where(np.isfinite(dist), self.offered_weight * scores, scores)
