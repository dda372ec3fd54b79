"""Damped least-squares inverse kinematics for the four DIGIT fingertips (MuJoCo Jacobians).

Each finger has 4 joints but a fingertip target has 5 constraints (gel centre position
and the pad normal direction), so position is the primary task and the pad direction
is pursued only in its null space (one spare degree of freedom, gain `normal_weight`):
the gel lands on the target point and tilts as close to the wanted direction as the
finger allows there. Fingers are independent chains, so
all four are solved together with one forward-kinematics pass per iteration.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from neuralfeels_sem.core.hand import FINGERS

MAX_STEP_RAD = 0.2


@dataclass
class FingerTarget:
    """Where a finger's gel centre should be and which way its pad (sensor +z) should face."""

    gel_position: np.ndarray  # (3,) world
    pad_direction: np.ndarray  # (3,) world unit vector = desired sensor +z (into the object)
    # Point of the gel surface that goes to gel_position: (x, y) in the sensor frame from the
    # gel centre. A pad tilted against the surface touches with an off-centre point; placing
    # that point keeps its press exact while the IK turns the pad about it.
    gel_offset: np.ndarray = (0.0, 0.0)

    def __post_init__(self) -> None:
        self.gel_position = np.asarray(self.gel_position, dtype=np.float64)
        self.pad_direction = np.asarray(self.pad_direction, dtype=np.float64)
        self.gel_offset = np.asarray(self.gel_offset, dtype=np.float64)
        if (
            self.gel_position.shape != (3,)
            or self.pad_direction.shape != (3,)
            or self.gel_offset.shape != (2,)
        ):
            raise ValueError(
                "FingerTarget needs (3,) gel_position and pad_direction and a (2,) gel_offset"
            )
        norm = np.linalg.norm(self.pad_direction)
        if norm < 1e-9:
            raise ValueError("FingerTarget.pad_direction must be non-zero")
        self.pad_direction = self.pad_direction / norm


class FingertipIK:
    """Solves joint angles that put each `<finger>_gel` site on its target.

    Works on any model containing the hand of hand_model.py (the hand alone or the full
    scene); it writes qpos of `data` and runs forward kinematics only.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        iterations: int = 25,
        damping: float = 1e-6,
        normal_weight: float = 0.5,
        tolerance_m: float = 1e-4,
    ) -> None:
        self.model, self.data = model, data
        self.iterations, self.damping = iterations, damping
        self.normal_weight, self.tolerance_m = normal_weight, tolerance_m
        self.site_ids = {
            f: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{f}_gel") for f in FINGERS
        }
        if min(self.site_ids.values()) < 0:
            raise ValueError("model has no <finger>_gel sites; build it with sim.hand_model")
        self.qpos_adr, self.dof_adr, self.limits = {}, {}, {}
        for f in FINGERS:
            ids = ids_of(model, f)
            self.qpos_adr[f] = np.array([model.jnt_qposadr[j] for j in ids])
            self.dof_adr[f] = np.array([model.jnt_dofadr[j] for j in ids])
            self.limits[f] = np.array([model.jnt_range[j] for j in ids])
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        self._site_body = {f: int(model.site_bodyid[s]) for f, s in self.site_ids.items()}

    def forward(self) -> None:
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def gel_pose(self, finger: str) -> tuple[np.ndarray, np.ndarray]:
        """Current (gel centre (3,), pad direction (3,)) of a finger in the world."""
        sid = self.site_ids[finger]
        return self.data.site_xpos[sid].copy(), self.data.site_xmat[sid].reshape(3, 3)[:, 2].copy()

    def gel_point(self, finger: str, offset: np.ndarray) -> np.ndarray:
        """World position of the gel surface point at sensor-frame (x, y) `offset` from its centre."""
        sid = self.site_ids[finger]
        rot = self.data.site_xmat[sid].reshape(3, 3)
        return self.data.site_xpos[sid] + rot[:, 0] * offset[0] + rot[:, 1] * offset[1]

    def solve(self, targets: dict[str, FingerTarget]) -> dict[str, float]:
        """Move the targeted fingers from the current qpos; return position error (m) per finger."""
        for finger in targets:
            if finger not in self.site_ids:
                raise ValueError(f"unknown finger {finger!r}; expected one of {FINGERS}")
        errors = dict.fromkeys(targets, np.inf)
        active = set(targets)
        eye3 = self.damping * np.eye(3)
        for _ in range(self.iterations):
            self.forward()
            for finger in list(active):
                target = targets[finger]
                pos, pad = self.gel_pose(finger)
                off_centre = target.gel_offset.any()
                if off_centre:
                    pos = self.gel_point(finger, target.gel_offset)
                err_p = target.gel_position - pos
                errors[finger] = float(np.sqrt(err_p @ err_p))
                err_r = _cross(pad, target.pad_direction)  # axis * sin(angle) toward the target
                if off_centre:
                    mujoco.mj_jac(
                        self.model, self.data, self._jacp, self._jacr, pos, self._site_body[finger]
                    )
                else:
                    mujoco.mj_jacSite(
                        self.model, self.data, self._jacp, self._jacr, self.site_ids[finger]
                    )
                dofs = self.dof_adr[finger]
                jp, jr = self._jacp[:, dofs], self._jacr[:, dofs]
                # Position first (damped least squares); the pad direction only in the
                # position task's null space (4 joints - 3 = 1 spare degree of freedom).
                dq = jp.T @ np.linalg.solve(jp @ jp.T + eye3, err_p)
                # The position task's exact null space is the one direction n with jp @ n = 0
                # (generalised cross product of jp's rows); move along it toward the pad
                # target. Damping there would leak into the position and slow it down.
                n = _null_direction(jp)
                jrn = jr @ n
                dq += self.normal_weight * n * (jrn @ (err_r - jr @ dq)) / (jrn @ jrn + 1e-2)
                step = np.abs(dq).max()
                if step > MAX_STEP_RAD:  # keep linearisation steps small near singularities
                    dq *= MAX_STEP_RAD / step
                adr = self.qpos_adr[finger]
                lim = self.limits[finger]
                before = self.data.qpos[adr].copy()
                self.data.qpos[adr] = np.clip(before + dq, lim[:, 0], lim[:, 1])
                # Converged on position, or stalled (the normal cannot be matched any better).
                moved = np.abs(self.data.qpos[adr] - before).max()
                if (errors[finger] < self.tolerance_m and moved < 5e-3) or moved < 1e-5:
                    active.discard(finger)
            if not active:
                break
        self.forward()
        for finger, target in targets.items():
            errors[finger] = float(
                np.linalg.norm(target.gel_position - self.gel_point(finger, target.gel_offset))
            )
        return errors


_DROP_ONE = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
_SIGNS = np.array([1.0, -1.0, 1.0, -1.0])


def _null_direction(jac: np.ndarray) -> np.ndarray:
    """Unit vector spanning the null space of a (3, 4) Jacobian (zero if it is rank-deficient).

    Its entries are the signed 3x3 minors of jac (the generalised cross product of its rows).
    """
    n = _SIGNS * np.linalg.det(jac[:, _DROP_ONE].transpose(1, 0, 2))
    norm = np.sqrt(n @ n)
    return n / norm if norm > 1e-12 else np.zeros(4)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross is slow for single vectors)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def ids_of(model: mujoco.MjModel, finger: str) -> list[int]:
    """Joint ids of a finger's four joints, proximal first."""
    return [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{finger}_j{i}") for i in range(4)]
