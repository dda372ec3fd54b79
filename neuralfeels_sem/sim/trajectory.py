"""Ground-truth object motion: steady rotation about a configured axis plus a small wobble.

HORA-like in-hand rotation: the object turns at a constant rate about `axis` (world
frame, through the grasp centre) while its axis nods by a few degrees and its centre
sways by a millimetre, as a real rotation policy's object does.

Optionally the object turns about `axis` and `alternate_axis` in turn, `alternate_every_s`
seconds each, as a multi-axis rotation policy does: about one axis the fingers only ever
touch a band round the object; a second axis brings its poles round to them.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.geometry import rotation_matrix


def perpendicular_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing `axis` to a right-handed orthonormal basis."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


class ObjectTrajectory:
    """world_T_object(t) for an object turning about `axis` through `centre`."""

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
    ) -> None:
        self.centre = np.asarray(centre, np.float64)
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
        self.segment_s = float(alternate_every_s) if len(self.axes) > 1 else np.inf
        self.speed = np.deg2rad(speed_deg_s)
        self.wobble = np.deg2rad(wobble_deg)
        self.wobble_hz, self.sway_m = wobble_hz, sway_m
        self.initial_rotation = (
            np.eye(3) if initial_rotation is None else np.asarray(initial_rotation, float)
        )
        self._u, self._v = perpendicular_basis(self.axis)
        self._phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)
        # Orientation (before the wobble) at the start of each segment, extended on demand.
        self._segment_starts = [self.initial_rotation]

    def segment(self, t: float) -> int:
        """Index of the segment (stretch of turning about one axis) that time t falls in."""
        return 0 if np.isinf(self.segment_s) else max(int(np.floor(t / self.segment_s)), 0)

    def segment_axis(self, k: int) -> np.ndarray:
        return self.axes[k % len(self.axes)]

    def segment_start(self, k: int) -> float:
        return 0.0 if k == 0 else k * self.segment_s

    def _turn(self, t: float) -> np.ndarray:
        """The rotation (before the wobble) at time t: segment after segment, continuous."""
        k = self.segment(t)
        while len(self._segment_starts) <= k:
            j = len(self._segment_starts) - 1
            step = rotation_matrix(self.segment_axis(j), self.speed * self.segment_s)
            self._segment_starts.append(step @ self._segment_starts[j])
        turned = rotation_matrix(self.segment_axis(k), self.speed * (t - self.segment_start(k)))
        return turned @ self._segment_starts[k]

    def pose(self, t: float) -> np.ndarray:
        w = 2 * np.pi * self.wobble_hz * t
        nod = rotation_matrix(self._u, self.wobble * np.sin(w + self._phase[0])) @ rotation_matrix(
            self._v, self.wobble * np.sin(0.7 * w + self._phase[1])
        )
        pose = np.eye(4)
        pose[:3, :3] = nod @ self._turn(t)
        pose[:3, 3] = self.centre + self.sway_m * np.sin(1.3 * w + self._phase[2]) * self._u
        return pose
