"""Sliding-window refinement of the last tracked poses (`mapping.tracker.window`).

Per-frame tracking fits each frame alone, against the field as it was then, and the pose
a frame is mapped with carries that fit into the field. The window re-solves the poses of
the last `frames` tracked frames against the current field, each with a subset of its own
points and its colour rows (the newest frame with all its rows) and, with a motion weight
above 0, tied together by constant-velocity motion residuals (consecutive relative motions
should differ little; the two tracked poses before the window are fixed as the motion's
anchor). Earlier frames whose pose moved are re-placed in the map by their pose source
(the mapper holds points in the object frame), so the field learns from the refined poses.
On the simulated rig it did not lower the pose error (docs/pose.md), so it is off.

Levenberg-Marquardt on one left se(3) increment per frame. The SDF rows' Jacobians are
[g, q x g] as in pose_tracker.py; the motion residuals' are central differences (six
numbers over at most three poses each: cheap, and no adjoint algebra to get wrong).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields

import numpy as np
import torch
from torch import Tensor

from neuralfeels_sem.core.geometry import invert_pose, orthonormalize_pose
from neuralfeels_sem.mapping.fit_check import divergence, inlier_share
from neuralfeels_sem.mapping.residual_terms import ResidualTerm, stack_terms
from neuralfeels_sem.mapping.se3 import constant_velocity, se3_exp, se3_log

JACOBIAN_STEP = 1e-6  # central-difference step of the motion residuals (m, rad)


@dataclass
class WindowConfig:
    """`mapping.tracker.window`: joint refinement of the last tracked poses (docs/pose.md).

    frames: poses refined jointly, the newest frame's included (0 or 1: off, every frame
        tracked alone).
    points_per_frame: SDF rows kept for each earlier frame (a random subset of those it
        was tracked with); the newest frame uses all of its rows.
    motion_weight: weight of each squared motion residual (translation in metres,
        rotation times the tracker's rotation_scale), relative to one frame's mean robust
        SDF cost. 0 refits each frame of the window on its own against the current field;
        at 0.1 the coupling pulled poses toward the extrapolated motion and the tracker
        lost frames it otherwise kept (docs/pose.md).
    iterations: Levenberg-Marquardt iterations of the joint solve.
    """

    frames: int = 0
    points_per_frame: int = 300
    motion_weight: float = 0.0
    iterations: int = 3

    def __post_init__(self) -> None:
        if self.frames < 0 or self.points_per_frame < 6 or self.iterations < 1:
            raise ValueError(
                f"mapping.tracker.window needs frames >= 0 ({self.frames}), points_per_frame "
                f">= 6 ({self.points_per_frame}) and iterations >= 1 ({self.iterations})"
            )
        if not self.motion_weight >= 0:
            raise ValueError(
                f"mapping.tracker.window.motion_weight={self.motion_weight} must be >= 0"
            )

    @classmethod
    def copy_of(cls, given: WindowConfig) -> WindowConfig:
        """A plain, checked copy of `given` (a config node read setting by setting)."""
        return cls(**{f.name: getattr(given, f.name) for f in fields(cls)})


@dataclass
class WindowFrame:
    """One frame of the window: its pose (world_T_object) and the world points it is
    aligned with, with their weights."""

    index: int
    pose: np.ndarray
    points: Tensor
    weights: Tensor
    terms: Sequence[ResidualTerm] = ()  # its colour rows: they see turns the SDF cannot


class PoseWindow:
    """The last tracked frames and the two fixed poses before them (see the module)."""

    def __init__(self, config: WindowConfig, tracker) -> None:
        self.config = WindowConfig.copy_of(config)
        self.tracker = tracker  # a PoseTracker: its robust loss, caps, checks and generator
        self.frames: list[WindowFrame] = []  # oldest first
        self.anchors: list[np.ndarray] = []  # up to two poses before the window, fixed
        self.solves = 0
        self.rejected = 0  # solves whose result failed the checks (per-frame poses kept)
        self.shifts_mm: list[float] = []  # how far each re-placed earlier frame moved

    @property
    def enabled(self) -> bool:
        return self.config.frames > 1

    def reset(self) -> None:
        """Forget the window (a frame was not tracked: the motion chain is broken)."""
        self.frames, self.anchors = [], []

    def refine(
        self,
        index: int,
        pose: np.ndarray,
        points_world: dict,
        sdf_fn: Callable[[Tensor], Tensor],
        terms: Sequence[ResidualTerm] = (),
    ) -> tuple[np.ndarray, dict[int, np.ndarray]]:
        """The newest frame's refined pose, and object_T_object corrections of earlier
        frames whose pose moved (index -> the transform re-placing their object-frame
        points). `pose` is the frame's tracked pose, `terms` its extra rows (colour)."""
        pts, weights = self.tracker._gather(points_world)
        newest = WindowFrame(index, np.asarray(pose, np.float64).copy(), pts, weights, terms)
        free = [*self.frames, newest]
        moves: dict[int, np.ndarray] = {}
        if len(free) > 1 or len(self.anchors) == 2:
            refined = self._solve(free, sdf_fn)
            if refined is not None:
                moves = self._apply(free, refined)
        keep = self._subset(newest.points, newest.weights)
        self.frames.append(WindowFrame(index, newest.pose, *keep, terms))
        while len(self.frames) >= self.config.frames:
            self.anchors = [*self.anchors, self.frames.pop(0).pose][-2:]
        return newest.pose, moves

    def _apply(self, free: list[WindowFrame], refined: list[np.ndarray]) -> dict:
        moves = {}
        for frame, new in zip(free, refined):
            if frame is not free[-1]:
                move = invert_pose(new) @ frame.pose
                moves[frame.index] = move
                self.shifts_mm.append(1e3 * float(np.linalg.norm(se3_log(move)[:3])))
            frame.pose = new
        return moves

    def _subset(self, pts: Tensor, weights: Tensor) -> tuple[Tensor, Tensor]:
        n = self.config.points_per_frame
        if len(pts) <= n:
            return pts, weights
        keep = torch.randperm(len(pts), generator=self.tracker.generator)[:n]
        return pts[keep], weights[keep]

    # ------------------------------------------------------------------ the solve
    def _solve(self, free: list[WindowFrame], sdf_fn) -> list[np.ndarray] | None:
        """Refined poses of `free` (None: the solve failed its checks)."""
        self.solves += 1
        rows = [stack_terms(sdf_fn, f.points, f.weights, f.terms) for f in free]
        x = [invert_pose(f.pose) for f in free]  # object_T_world, the unknowns
        lins = [self._evaluate(fn, xi, p, w) for (fn, p, w), xi in zip(rows, x)]
        cost = sum(lin.cost for lin in lins) + self._motion_cost(x)
        mu = self.tracker.damping
        for _ in range(self.config.iterations):
            h, b = self._normal_equations(lins, rows, x)
            accepted = False
            # Unlike the tracker's solve, no cap on rejected trials: the window's figures
            # (docs/pose.md) were measured this way.
            while mu < 1e8 and not accepted:
                delta = -np.linalg.solve(h + mu * np.diag(np.diag(h) + 1e-12), b)
                if self._too_far(delta):
                    mu *= 10.0
                    continue
                trial = [se3_exp(delta[6 * i : 6 * i + 6]) @ xi for i, xi in enumerate(x)]
                trial_lins = [
                    self._evaluate(fn, xi, p, w, False) for (fn, p, w), xi in zip(rows, trial)
                ]
                trial_cost = sum(lin.cost for lin in trial_lins) + self._motion_cost(trial)
                if trial_cost <= cost:
                    x, cost, accepted = trial, trial_cost, True
                    lins = [self._evaluate(fn, xi, p, w) for (fn, p, w), xi in zip(rows, x)]
                    mu = max(mu / 10.0, 1e-9)
                else:
                    mu *= 10.0
            if not accepted:
                break
        refined = [orthonormalize_pose(invert_pose(xi)) for xi in x]
        if not self._fits(free, refined, lins[-1]):
            self.rejected += 1
            return None
        return refined

    def _evaluate(self, fn, obj_T_world, pts, weights, gradient: bool = True):
        return self.tracker._evaluate(fn, obj_T_world, pts, weights, _no_prior, gradient)

    def _normal_equations(self, lins, rows, x) -> tuple[np.ndarray, np.ndarray]:
        """Block-diagonal SDF (and colour) terms plus the motion residuals' coupling."""
        n = len(x)
        h, b = np.zeros((6 * n, 6 * n)), np.zeros(6 * n)
        for i, (lin, (_, _, w)) in enumerate(zip(lins, rows)):
            hi, bi = self.tracker._normal_equations(lin, w, None)
            h[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] += hi
            b[6 * i : 6 * i + 6] += bi
        e, jac = self._motion_jacobian(x)
        if len(e):
            scale = np.tile(self._scale() ** 2, len(e) // 6) * self.config.motion_weight
            h += jac.T @ (scale[:, None] * jac)
            b += jac.T @ (scale * e)
        return h, b

    def _scale(self) -> np.ndarray:
        return np.array([1.0, 1.0, 1.0] + [self.tracker.rotation_scale] * 3)

    def _motion_residuals(self, x: list[np.ndarray]) -> np.ndarray:
        """Left error of each free pose against the constant-velocity prediction from the
        two poses before it (anchors included), stacked (6 per pose that has two)."""
        poses = [*self.anchors, *(invert_pose(xi) for xi in x)]
        first = len(self.anchors)
        out = [
            se3_log(orthonormalize_pose(x[k - first] @ constant_velocity(poses[k - 2 : k])))
            for k in range(max(first, 2), len(poses))
        ]
        return np.concatenate(out) if out else np.zeros(0)

    def _motion_cost(self, x: list[np.ndarray]) -> float:
        e = self._motion_residuals(x)
        scaled = e * np.tile(self._scale(), len(e) // 6)
        return self.config.motion_weight * float(scaled @ scaled)

    def _motion_jacobian(self, x: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        e = self._motion_residuals(x)
        jac = np.zeros((len(e), 6 * len(x)))
        if not len(e) or self.config.motion_weight == 0:
            return np.zeros(0), jac[:0]
        for column in range(6 * len(x)):
            i, step = divmod(column, 6)
            xi = np.zeros(6)
            xi[step] = JACOBIAN_STEP
            plus, minus = list(x), list(x)
            plus[i], minus[i] = se3_exp(xi) @ x[i], se3_exp(-xi) @ x[i]
            jac[:, column] = (self._motion_residuals(plus) - self._motion_residuals(minus)) / (
                2 * JACOBIAN_STEP
            )
        return e, jac

    def _too_far(self, delta: np.ndarray) -> bool:
        steps = delta.reshape(-1, 6)
        return bool(
            (np.linalg.norm(steps[:, :3], axis=1) > self.tracker.max_step_m).any()
            or (np.linalg.norm(steps[:, 3:], axis=1) > self.tracker.max_step_rad).any()
        )

    def _fits(self, free: list[WindowFrame], refined: list[np.ndarray], newest) -> bool:
        """A refinement, not a jump: every pose within the tracker's motion caps of where
        it was, and the newest frame still fitting (its inlier share)."""
        t = self.tracker
        for frame, new in zip(free, refined):
            if divergence(new, frame.pose, t.max_motion_m, t.max_motion_rad):
                return False
        n = len(free[-1].points)
        share = inlier_share(newest.r[:n], free[-1].weights, t.inlier_m)
        return share >= t.min_inlier_share

    # ------------------------------------------------------------------ outputs
    def metrics(self) -> dict:
        shifts = self.shifts_mm
        return {
            "pose_window_solves": self.solves,
            "pose_window_rejected": self.rejected,
            "pose_window_shift_mm": float(np.mean(shifts)) if shifts else 0.0,
        }

    def state(self) -> dict:
        """The counts only: a frame's colour rows are closures over views that are not kept
        once it is past, so a resumed run starts its window again (docs/pose.md)."""
        return {"solves": self.solves, "rejected": self.rejected, "shifts_mm": list(self.shifts_mm)}

    def load_state(self, state: dict) -> None:
        self.reset()
        self.solves = int(state.get("solves", 0))
        self.rejected = int(state.get("rejected", 0))
        self.shifts_mm = [float(v) for v in state.get("shifts_mm", [])]


def _no_prior(_: np.ndarray) -> None:
    """The window's motion residuals replace the tracker's per-frame prior."""
    return None
