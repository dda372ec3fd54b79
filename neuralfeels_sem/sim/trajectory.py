"""Ground-truth object motion: steady rotation about a configured axis plus a small wobble.

HORA-like in-hand rotation: the object turns at a constant rate about `axis` (world
frame, through the grasp centre) while its axis nods by a few degrees and its centre
sways by a millimetre, as a real rotation policy's object does.

Optionally the object turns about `axis` and `alternate_axis` in turn, `alternate_every_s`
seconds each, as a multi-axis rotation policy does: about one axis the fingers only ever
touch a band round the object; a second axis brings its poles round to them.

`regrasp(t, axis, offset)` (sensor.policy=active, sim/touch_planner.py) starts a new
stretch at t: the object turns about `axis` from then on and its centre slides to
`offset` from the grasp centre over `slide_s` (as a hand that regrasps an object larger
than its reach). Poses already asked for never change: a regrasp starts no earlier than
the latest time queried.

With a `RestHeight` (sensor.grasp_height=follow) the centre also rises along the palm
normal by just as much as the current orientation needs for the object's lowest point to
clear the palm: an object lying flat rests low between the fingers instead of at the height
its most upright orientation would need.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.geometry import rotation_matrix

# sensor.grasp_height: fixed (the centre as high as any orientation needs) | follow (RestHeight)
GRASP_HEIGHTS = ("fixed", "follow")


def check_grasp_height(value: str, name: str = "grasp_height") -> None:
    """ValueError naming `name` unless `value` is one of GRASP_HEIGHTS."""
    if value not in GRASP_HEIGHTS:
        raise ValueError(f"{name}={value!r}: use one of {', '.join(GRASP_HEIGHTS)}")


def perpendicular_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing `axis` to a right-handed orthonormal basis."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


class RestHeight:
    """How far an orientation lifts the object's centre above the grasp centre.

    `points`: (N, 3) object-frame points whose lowest one bounds the object (its convex
    hull's vertices); `up`: the palm normal (world); `room`: how far below the grasp centre
    the lowest point may reach (the palm face's clearance). lift(R) = max(0, depth - room)
    with depth = how far the lowest point of the object turned by R lies below its centre.
    """

    def __init__(self, points: np.ndarray, up: np.ndarray, room: float) -> None:
        self.points = np.asarray(points, np.float64).reshape(-1, 3)
        if not len(self.points):
            raise ValueError("RestHeight needs at least one object point")
        self.up = np.asarray(up, np.float64) / np.linalg.norm(up)
        self.room = float(room)

    def lift(self, rotation: np.ndarray) -> float:
        depth = float(np.max(-(self.points @ (rotation.T @ self.up))))
        return max(0.0, depth - self.room)


class ObjectTrajectory:
    """world_T_object(t) for an object turning about `axis` through `centre` (+ the grasp offset)."""

    def __init__(
        self,
        centre: np.ndarray,
        axis: np.ndarray = (0.0, 0.0, 1.0),
        speed_deg_s: float = 30.0,
        wobble_deg: float = 4.0,
        wobble_hz: float = 0.3,
        sway_m: float = 0.001,
        initial_rotation: np.ndarray | None = None,
        seed: int = 0,
        alternate_axis: np.ndarray | None = None,
        alternate_every_s: float = 5.0,
        slide_s: float = 1.0,
        rest: RestHeight | None = None,
    ) -> None:
        self.centre = np.asarray(centre, np.float64)
        self.rest = rest
        axis = np.asarray(axis, np.float64)
        if self.centre.shape != (3,) or axis.shape != (3,) or np.linalg.norm(axis) < 1e-9:
            raise ValueError(
                f"need a (3,) centre and a non-zero (3,) axis, got {self.centre} and {axis}"
            )
        self.axis = axis / np.linalg.norm(axis)
        self.axes = [self.axis]
        if alternate_axis is not None:
            other = np.asarray(alternate_axis, np.float64)
            if other.shape != (3,) or np.linalg.norm(other) < 1e-9:
                raise ValueError(f"alternate_axis must be a non-zero (3,) vector, got {other}")
            if alternate_every_s <= 0:
                raise ValueError(f"alternate_every_s must be > 0, got {alternate_every_s}")
            self.axes.append(other / np.linalg.norm(other))
        if slide_s <= 0:
            raise ValueError(f"slide_s must be > 0, got {slide_s}")
        self.segment_s = float(alternate_every_s) if len(self.axes) > 1 else np.inf
        self.speed = np.deg2rad(speed_deg_s)
        self.wobble = np.deg2rad(wobble_deg)
        self.wobble_hz, self.sway_m, self.slide_s = wobble_hz, sway_m, float(slide_s)
        self.initial_rotation = (
            np.eye(3) if initial_rotation is None else np.asarray(initial_rotation, float)
        )
        self._u, self._v = perpendicular_basis(self.axis)
        self._phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)
        # Stretches of turning about one axis, extended on demand; a regrasp starts one.
        zero = np.zeros(3)
        self._segments = [_Segment(0.0, self.axis, self.initial_rotation, zero, zero, 0)]
        self.horizon_s = 0.0  # latest time asked for: a regrasp starts no earlier
        self.regrasps: list[tuple[float, np.ndarray, np.ndarray]] = []  # (time, axis, offset)

    def _extend(self, t: float) -> None:
        """Add the alternation's stretches up to time t."""
        while True:
            last = self._segments[-1]
            end = last.base_s + (last.periodic + 1) * self.segment_s
            if t < end:
                return
            # the stretch before the last one gives the next axis (ping-pong); first: axes[1]
            prior = self._segments[-2].axis if len(self._segments) > 1 else self.axes[1]
            step = rotation_matrix(last.axis, self.speed * (end - last.start_s))
            self._segments.append(
                _Segment(
                    end,
                    prior,
                    step @ last.rotation,
                    last.offset,
                    last.offset,
                    last.periodic + 1,
                    last.base_s,
                )
            )

    def segment(self, t: float) -> int:
        """Index of the segment (stretch of turning about one axis) that time t falls in."""
        self.horizon_s = max(self.horizon_s, t)
        return self._index(t)

    def _index(self, t: float) -> int:
        """segment(t) without counting t as asked for (a preview moves no horizon)."""
        self._extend(t)
        starts = [s.start_s for s in self._segments]
        return max(int(np.searchsorted(starts, t, side="right")) - 1, 0)

    def steady_poses(self, times: np.ndarray) -> np.ndarray:
        """(K, 4, 4) poses the plan holds at `times`, without wobble or sway; a preview:
        no time counts as asked for, so a regrasp may still start before them."""
        out = np.tile(np.eye(4), (len(times), 1, 1))
        for pose, t in zip(out, times):
            seg = self._segments[self._index(float(t))]
            pose[:3, :3] = rotation_matrix(seg.axis, self.speed * (t - seg.start_s)) @ seg.rotation
            pose[:3, 3] = self.centre + self._offset(seg, float(t)) + self._lift(pose[:3, :3])
        return out

    def turn_poses(self, t0: float, axis: np.ndarray, ahead: np.ndarray) -> np.ndarray:
        """(K, 4, 4) steady poses at t0 + ahead were the object to turn about `axis` from t0
        on (`turn`), keeping its place in the grasp; a preview, as steady_poses."""
        start = self.steady_poses(np.array([t0]))[0]
        axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
        out = np.tile(start, (len(ahead), 1, 1))
        base = start[:3, 3] - self._lift(start[:3, :3])
        for pose, tau in zip(out, ahead):
            pose[:3, :3] = rotation_matrix(axis, self.speed * float(tau)) @ start[:3, :3]
            pose[:3, 3] = base + self._lift(pose[:3, :3])
        return out

    def turn(self, t: float, axis: np.ndarray) -> tuple[int, float]:
        """A regrasp that only changes the axis: the object keeps its place in the grasp."""
        k = self._index(max(float(t), self.horizon_s))
        return self.regrasp(t, axis, self._segments[k].offset)

    def segment_axis(self, k: int) -> np.ndarray:
        self._extend_to_index(k)
        return self._segments[k].axis

    def next_axis(self, t: float) -> np.ndarray:
        """The axis of the stretch after the one time t falls in (a preview, as steady_poses)."""
        k = self._index(float(t))
        self._extend_to_index(k + 1)
        return self._segments[k + 1].axis

    def segment_start(self, k: int) -> float:
        self._extend_to_index(k)
        return self._segments[k].start_s

    def segment_centre(self, k: int) -> np.ndarray:
        """Where the object's centre settles in segment k (after the slide of a regrasp)."""
        self._extend_to_index(k)
        return self.centre + self._segments[k].offset

    def settled(self, k: int) -> float:
        """A time in segment k after its slide (the start when nothing slides)."""
        seg = self.segment_start(k)
        moved = np.any(self._segments[k].offset != self._segments[k].offset_from)
        return seg + self.slide_s if moved else seg

    def _extend_to_index(self, k: int) -> None:
        while len(self._segments) <= k and np.isfinite(self.segment_s):
            last = self._segments[-1]
            self._extend(last.base_s + (last.periodic + 1) * self.segment_s)
        if k >= len(self._segments):
            raise IndexError(f"segment {k} does not exist (one axis, no regrasp)")

    def regrasp(self, t: float, axis: np.ndarray, offset: np.ndarray) -> tuple[int, float]:
        """From t (or the latest time asked for, if later): turn about `axis`, slide to `offset`.

        Returns the new segment's index and start time.
        """
        axis = np.asarray(axis, np.float64)
        start = max(float(t), self.horizon_s)
        k = self.segment(start)
        last = self._segments[k]
        del self._segments[k + 1 :]  # only stretches after the horizon: never used yet
        step = rotation_matrix(last.axis, self.speed * (start - last.start_s))
        offset_from = self._offset(last, start)
        self._segments.append(
            _Segment(
                start,
                axis / np.linalg.norm(axis),
                step @ last.rotation,
                offset_from,
                np.asarray(offset, np.float64),
                0,
                start,
            )
        )
        self.regrasps.append((start, self._segments[-1].axis, self._segments[-1].offset))
        return len(self._segments) - 1, start

    def _offset(self, seg: _Segment, t: float) -> np.ndarray:
        """The grasp offset at time t in `seg`: a smooth slide from offset_from to offset."""
        w = float(np.clip((t - seg.start_s) / self.slide_s, 0.0, 1.0))
        w = w * w * (3.0 - 2.0 * w)
        return (1.0 - w) * seg.offset_from + w * seg.offset

    def _lift(self, rotation: np.ndarray) -> np.ndarray | float:
        """The centre's rise along the palm normal in an orientation (0.0 without a rest:
        pose() runs many times a frame, so the default adds a scalar, not a new array)."""
        return 0.0 if self.rest is None else self.rest.lift(rotation) * self.rest.up

    def pose(self, t: float) -> np.ndarray:
        seg = self._segments[self.segment(t)]
        turned = rotation_matrix(seg.axis, self.speed * (t - seg.start_s)) @ seg.rotation
        w = 2 * np.pi * self.wobble_hz * t
        nod = rotation_matrix(self._u, self.wobble * np.sin(w + self._phase[0])) @ rotation_matrix(
            self._v, self.wobble * np.sin(0.7 * w + self._phase[1])
        )
        pose = np.eye(4)
        pose[:3, :3] = nod @ turned
        sway = self.sway_m * np.sin(1.3 * w + self._phase[2]) * self._u
        pose[:3, 3] = self.centre + self._offset(seg, t) + sway + self._lift(turned)
        return pose


class _Segment:
    """A stretch of turning about one axis from `start_s` (rotation: the orientation then).

    The grasp offset slides from `offset_from` to `offset` at its start. `periodic`
    counts the alternation's stretches since `base_s` (0 or a regrasp's time).
    """

    def __init__(
        self,
        start_s: float,
        axis: np.ndarray,
        rotation: np.ndarray,
        offset_from: np.ndarray,
        offset: np.ndarray,
        periodic: int,
        base_s: float = 0.0,
    ) -> None:
        self.start_s, self.axis, self.rotation = start_s, axis, rotation
        self.offset_from, self.offset = offset_from, offset
        self.periodic, self.base_s = periodic, base_s
