"""Ground-truth object motion: steady rotation about a configured axis plus a small wobble.

HORA-like in-hand rotation: the object turns at a constant rate about `axis` (world
frame, through the grasp centre) while its axis nods by a few degrees and its centre
sways by a millimetre, as a real rotation policy's object does.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.utils.geometry import rotation_matrix


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
    ) -> None:
        self.centre = np.asarray(centre, np.float64)
        axis = np.asarray(axis, np.float64)
        if self.centre.shape != (3,) or axis.shape != (3,) or np.linalg.norm(axis) < 1e-9:
            raise ValueError(
                f"need a (3,) centre and a non-zero (3,) axis, got {self.centre} and {axis}"
            )
        self.axis = axis / np.linalg.norm(axis)
        self.speed = np.deg2rad(speed_deg_s)
        self.wobble = np.deg2rad(wobble_deg)
        self.wobble_hz, self.sway_m = wobble_hz, sway_m
        self.initial_rotation = (
            np.eye(3) if initial_rotation is None else np.asarray(initial_rotation, float)
        )
        self._u, self._v = perpendicular_basis(self.axis)
        self._phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)

    def pose(self, t: float) -> np.ndarray:
        w = 2 * np.pi * self.wobble_hz * t
        nod = rotation_matrix(self._u, self.wobble * np.sin(w + self._phase[0])) @ rotation_matrix(
            self._v, self.wobble * np.sin(0.7 * w + self._phase[1])
        )
        pose = np.eye(4)
        pose[:3, :3] = nod @ rotation_matrix(self.axis, self.speed * t) @ self.initial_rotation
        pose[:3, 3] = self.centre + self.sway_m * np.sin(1.3 * w + self._phase[2]) * self._u
        return pose
