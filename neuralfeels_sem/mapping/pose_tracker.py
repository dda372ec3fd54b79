"""Object pose tracking against a signed distance field (NeuralFeels' pose optimiser).

Points observed in the world (camera and touch) should lie on the object's zero level
set: with q_i = object_T_world p_i the residual is r_i = sdf(q_i). Levenberg-Marquardt on
a left se(3) increment xi = (v, w), q_i <- exp(xi) q_i ~ q_i + w x q_i + v, whose
Jacobian row is [g_i, q_i x g_i] with g_i the SDF gradient at q_i (autograd). Robust
weights (Huber or Cauchy) keep points on parts of the surface the field has not learned
yet from dragging the pose; a prior residual pulls toward the motion model's prediction
and holds directions the points cannot see (a sphere's spin).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from neuralfeels_sem.core.geometry import check_pose, invert_pose
from neuralfeels_sem.mapping import fit_check
from neuralfeels_sem.mapping.colour_keyframes import ColourConfig
from neuralfeels_sem.mapping.fit_check import conditioning, divergence, fit_failure, inlier_share
from neuralfeels_sem.mapping.pose_window import WindowConfig
from neuralfeels_sem.mapping.residual_terms import (
    ROBUST_LOSSES,
    ResidualTerm,
    robust_weights,
    stack_terms,
)
from neuralfeels_sem.mapping.se3 import constant_velocity, se3_exp, se3_log
from neuralfeels_sem.mapping.track_points import gather_points

log = logging.getLogger(__name__)

__all__ = ["PoseTracker", "ResidualTerm", "TrackerConfig", "constant_velocity"]
__all__ += ["robust_weights", "se3_exp", "se3_log"]  # re-exported for callers and tests

REJECTIONS_BEFORE_STOP = 4  # trial steps that raise the cost before a solve ends


@dataclass
class TrackerConfig:
    """`mapping.tracker`: PoseTracker's settings (used when mapping.pose=track*).

    max_step_m, max_step_rad: the largest translation / rotation one LM step may make;
        a larger step is treated like a failed one (more damping). Far from the surface
        the field's SDF is clamped and flat, and an undamped step once threw the pose
        10^27 m away.
    max_motion_m, max_motion_rad: a result further than this from the starting (or
        predicted) pose is rejected as diverged and the prediction kept.
    prior_weight: weight of the squared distance to the predicted pose, relative to the
        mean squared SDF residual (translation in metres, rotation times rotation_scale).
        Weak on purpose: it only holds directions the points cannot see. At 0.01 it held
        the zero-velocity start of a run and the tracker lagged the true motion.
    source_weights: per-point weight by source ("camera", or a finger name; "tactile"
        applies to every finger); 0 drops that modality from tracking. Touch is weighted
        below the camera: a DIGIT holds its place while the surface slides under it, so
        a touch alone fits "the object did not move" well, but beside the camera points
        the touches pin what a smooth, partly hidden view leaves loose, such as the spin
        of a round handle about its own axis (docs/pose.md).
    max_points_per_source, max_points_per_finger: the camera's and each finger's points
        beyond these are subsampled at random each frame (the SDF batch sets the cost).
    inlier_m, min_inlier_share, min_conditioning: a solve counts as tracked only when at
        least min_inlier_share of the (weighted) points end within inlier_m of the
        surface and its conditioning (fit_check.py) is at least min_conditioning.
    fit_window, max_inlier_drop: a solve whose inlier share falls more than
        max_inlier_drop below the median of the last fit_window tracked frames is a poor
        fit too (1 switches this relative check off): a slide into a wrong basin keeps
        most points near a smooth surface, but fewer than before.
    relocalise_deg: a frame whose solves from the prediction and from the last pose both
        fail is solved again from the last pose turned by +-relocalise_deg about each
        object axis (through the frame's points), and the best fitting solve is kept
        (0 switches re-localisation off).
    """

    iterations: int = 8  # Levenberg-Marquardt iterations per frame (most frames stop sooner)
    # A RobustLoss; typed `str` because OmegaConf 2.3 rejects Literal annotations.
    robust_loss: str = "cauchy"
    robust_scale: float = 0.001  # metres where the robust loss stops being quadratic
    min_points: int = 50  # fewer points: keep the predicted pose (>= 6 pose unknowns)
    damping: float = 1.0e-3  # initial LM damping
    prior_weight: float = 1.0e-4  # pull toward the constant-velocity prediction
    rotation_scale: float = 0.05  # metres per radian in the prior (about the object radius)
    max_step_m: float = 0.01
    max_step_rad: float = 0.2
    max_motion_m: float = 0.03
    max_motion_rad: float = 0.5
    max_points_per_source: int = 1000  # camera points (a random subset beyond)
    max_points_per_finger: int = 200  # each finger's touch points
    source_weights: dict[str, float] = field(
        default_factory=lambda: {"camera": 1.0, "tactile": 0.5}
    )
    inlier_m: float = 0.002  # about 5x the camera's depth noise on the surface
    min_inlier_share: float = 0.5
    min_conditioning: float = 1.0e-4
    fit_window: int = 10
    max_inlier_drop: float = 0.1
    relocalise_deg: float = 15.0
    tolerance: float = 1.0e-6  # stop when a step changes the pose less than this (m, rad)
    colour: ColourConfig = field(default_factory=ColourConfig)  # colour_keyframes.py
    window: WindowConfig = field(default_factory=WindowConfig)  # pose_window.py
    seed: int = 0

    def __post_init__(self) -> None:
        if self.iterations < 1:
            raise ValueError(f"mapping.tracker.iterations={self.iterations} must be >= 1")
        if self.robust_loss not in ROBUST_LOSSES:
            raise ValueError(
                f"mapping.tracker.robust_loss={self.robust_loss!r} must be one of {ROBUST_LOSSES}"
            )
        positive = (
            "robust_scale", "damping", "rotation_scale", "tolerance",
            "max_step_m", "max_step_rad", "max_motion_m", "max_motion_rad", "inlier_m",
        )  # fmt: skip
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"mapping.tracker.{name}={getattr(self, name)} must be > 0")
        if not 0 <= self.min_inlier_share <= 1 or self.min_conditioning < 0:
            raise ValueError(
                f"mapping.tracker needs 0 <= min_inlier_share <= 1 ({self.min_inlier_share}) "
                f"and min_conditioning >= 0 ({self.min_conditioning})"
            )
        if self.fit_window < 1 or not 0 < self.max_inlier_drop <= 1:
            raise ValueError(
                f"mapping.tracker needs fit_window >= 1 ({self.fit_window}) and "
                f"0 < max_inlier_drop <= 1 ({self.max_inlier_drop}; 1 switches the check off)"
            )
        if not 0 <= self.relocalise_deg < 90:
            raise ValueError(
                f"mapping.tracker.relocalise_deg={self.relocalise_deg} must be in [0, 90) "
                "(0 switches re-localisation off)"
            )
        if self.prior_weight < 0:
            raise ValueError(f"mapping.tracker.prior_weight={self.prior_weight} must be >= 0")
        if self.min_points < 6 or min(self.max_points_per_source, self.max_points_per_finger) < 1:
            raise ValueError(
                f"mapping.tracker needs min_points >= 6 ({self.min_points}; six pose unknowns), "
                f"max_points_per_source >= 1 ({self.max_points_per_source}) and "
                f"max_points_per_finger >= 1 ({self.max_points_per_finger})"
            )
        if any(w < 0 for w in self.source_weights.values()):
            raise ValueError(
                f"mapping.tracker.source_weights={dict(self.source_weights)} must be >= 0"
            )


@dataclass
class _Linearisation:
    """The alignment at one pose: object-frame points q, residuals r, SDF gradients g,
    the prior error, the cost and the robust weights."""

    obj_T_world: np.ndarray
    q: Tensor
    r: Tensor
    g: Tensor | None  # None for a trial pose scored by its cost alone
    err: np.ndarray | None
    cost: float
    w: Tensor


class PoseTracker:
    """Levenberg-Marquardt alignment of world points to an object-frame SDF."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        config = config or TrackerConfig()  # ranges: TrackerConfig.__post_init__
        self.iterations = config.iterations
        self.robust_loss = config.robust_loss
        self.robust_scale = float(config.robust_scale)
        self.min_points = config.min_points
        self.damping = float(config.damping)
        self.prior_weight = float(config.prior_weight)
        self.rotation_scale = float(config.rotation_scale)
        self.max_points_per_source = config.max_points_per_source
        self.max_points_per_finger = config.max_points_per_finger
        self.source_weights = dict(config.source_weights)
        self.tolerance = float(config.tolerance)
        self.max_step_m = float(config.max_step_m)
        self.max_step_rad = float(config.max_step_rad)
        self.max_motion_m = float(config.max_motion_m)
        self.max_motion_rad = float(config.max_motion_rad)
        self.inlier_m = float(config.inlier_m)
        self.min_inlier_share = float(config.min_inlier_share)
        self.min_conditioning = float(config.min_conditioning)
        self.fit_window = int(config.fit_window)
        self.max_inlier_drop = float(config.max_inlier_drop)
        self.relocalise_deg = float(config.relocalise_deg)
        self.colour = ColourConfig.copy_of(config.colour)
        self.window = WindowConfig.copy_of(config.window)
        self.generator = torch.Generator().manual_seed(int(config.seed))

    def source_weight(self, source: str) -> float:
        if source in self.source_weights:
            return float(self.source_weights[source])
        default = "camera" if source == "camera" else "tactile"
        return float(self.source_weights.get(default, 1.0))

    def _gather(self, points_world: Mapping[str, Tensor]) -> tuple[Tensor, Tensor]:
        """All usable points (N, 3) float64 and their per-point source weights (N,)."""
        caps = {"camera": self.max_points_per_source}
        return gather_points(
            points_world, self.source_weight, caps, self.max_points_per_finger, self.generator
        )

    def _linearise(
        self,
        sdf_fn: Callable[[Tensor], Tensor],
        object_T_world: np.ndarray,
        pts: Tensor,
        gradient: bool = True,
    ) -> tuple[Tensor, Tensor, Tensor | None]:
        """Object-frame points q, residuals r = sdf(q) and, with `gradient`, d sdf / d q
        (float64), all points in one forward (and one backward) pass."""
        t = torch.as_tensor(object_T_world, dtype=torch.float64)
        q = pts @ t[:3, :3].T + t[:3, 3]
        x = q.to(torch.float32)
        if not gradient:  # a trial step only needs its cost: no graph, no backward pass
            with torch.no_grad():
                return q, sdf_fn(x).reshape(len(x)).to(torch.float64), None
        with torch.enable_grad():
            x.requires_grad_(True)
            sdf = sdf_fn(x).reshape(len(x))
            (grad,) = torch.autograd.grad(sdf.sum(), x)
        return q, sdf.detach().to(torch.float64), grad.to(torch.float64)

    def _cost(
        self, r: Tensor, weights: Tensor, prior_err: np.ndarray | None
    ) -> tuple[float, Tensor]:
        w_robust, rho = robust_weights(r, self.robust_loss, self.robust_scale)
        data = float((weights * rho).sum() / weights.sum())
        prior = 0.0
        if prior_err is not None:
            scaled = prior_err * self._prior_scale()
            prior = self.prior_weight * float(scaled @ scaled)
        return data + prior, w_robust * weights

    def _prior_scale(self) -> np.ndarray:
        return np.array([1.0, 1.0, 1.0] + [self.rotation_scale] * 3)

    def _prior_error(
        self, pred_world_T_object: np.ndarray | None
    ) -> Callable[[np.ndarray], np.ndarray | None]:
        """object_T_world -> its left error against the prediction (None: no prior term)."""

        def prior_error(t: np.ndarray) -> np.ndarray | None:
            # Left error of object_T_world against the prediction: exp(xi) shifts it by ~xi.
            if pred_world_T_object is None or self.prior_weight == 0:
                return None
            return se3_log(t @ pred_world_T_object)

        return prior_error

    def _evaluate(
        self,
        sdf_fn: Callable[[Tensor], Tensor],
        obj_T_world: np.ndarray,
        pts: Tensor,
        weights: Tensor,
        prior_error: Callable[[np.ndarray], np.ndarray | None],
        gradient: bool = True,
    ) -> _Linearisation:
        q, r, g = self._linearise(sdf_fn, obj_T_world, pts, gradient)
        err = prior_error(obj_T_world)
        cost, w = self._cost(r, weights, err)
        return _Linearisation(obj_T_world, q, r, g, err, cost, w)

    def _with_gradient(self, sdf_fn: Callable[[Tensor], Tensor], lin: _Linearisation, pts: Tensor):
        """`lin` with its SDF gradients (computed once the trial step was accepted)."""
        q, r, g = self._linearise(sdf_fn, lin.obj_T_world, pts)
        return _Linearisation(lin.obj_T_world, q, r, g, lin.err, lin.cost, lin.w)

    def _normal_equations(
        self, cur: _Linearisation, weights: Tensor, prior_h: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Newton H and b of the weighted residuals (and the prior) at `cur`."""
        jac = torch.cat([cur.g, torch.linalg.cross(cur.q, cur.g)], dim=1)
        norm = float(weights.sum())
        h = ((jac * cur.w[:, None]).T @ jac).numpy() / norm
        b = ((jac * cur.w[:, None]).T @ cur.r).numpy() / norm
        if cur.err is not None:
            h = h + prior_h
            b = b + prior_h @ cur.err
        return h, b

    def _minimise(
        self,
        sdf_fn: Callable[[Tensor], Tensor],
        cur: _Linearisation,
        pts: Tensor,
        weights: Tensor,
        prior_error: Callable[[np.ndarray], np.ndarray | None],
        info: dict,
    ) -> _Linearisation:
        """Levenberg-Marquardt from `cur`; counts iterations and evaluations in `info`.

        Trial steps are scored by a forward pass alone; the gradient is computed only at
        an accepted pose. An iteration whose last REJECTIONS_BEFORE_STOP trials all raise
        the cost ends the solve: at a minimum, more damping only shortens the step.
        """
        mu = self.damping
        prior_h = self.prior_weight * np.diag(self._prior_scale() ** 2)
        for it in range(self.iterations):
            info["iterations"] = it + 1
            h, b = self._normal_equations(cur, weights, prior_h)
            step, rejections = None, 0
            while mu < 1e8 and rejections < REJECTIONS_BEFORE_STOP:
                lhs = h + mu * np.diag(np.diag(h) + 1e-12)
                delta = -np.linalg.solve(lhs, b)
                too_far = np.linalg.norm(delta[:3]) > self.max_step_m
                if too_far or np.linalg.norm(delta[3:]) > self.max_step_rad:
                    mu *= 10.0
                    continue
                cand = self._evaluate(
                    sdf_fn, se3_exp(delta) @ cur.obj_T_world, pts, weights, prior_error, False
                )
                info["evaluations"] += 1
                if cand.cost <= cur.cost:
                    step, cur = delta, self._with_gradient(sdf_fn, cand, pts)
                    mu = max(mu / 10.0, 1e-9)
                    break
                mu *= 10.0
                rejections += 1
            if step is None or np.linalg.norm(step) < self.tolerance:
                break
        return cur

    def track(
        self,
        points_world: Mapping[str, Tensor | np.ndarray],
        sdf_fn: Callable[[Tensor], Tensor],
        init_world_T_object: np.ndarray,
        prior: np.ndarray | None = None,
        terms: Sequence[ResidualTerm] = (),
    ) -> tuple[np.ndarray, dict]:
        """world_T_object that puts the points on sdf_fn's zero level set, and a report.

        points_world: (N, 3) world-frame points per source. sdf_fn: (N, 3) float32
        object-frame points -> (N,) signed distances, differentiable in its input.
        prior: the predicted world_T_object the prior pulls toward (None: no prior).
        terms: further residuals solved jointly (residual_terms.py; e.g. colour against
        earlier views); the fit checks read the SDF rows alone.
        With fewer than `min_points` points the prior (else the initial pose) comes back
        unchanged with info["skipped"] set.
        """
        check_pose(init_world_T_object, "init_world_T_object")
        if prior is not None:
            check_pose(prior, "prior")
        sdf_pts, sdf_weights = self._gather(points_world)
        info: dict = {"points": len(sdf_pts), "iterations": 0, "evaluations": 0, "skipped": None}
        fallback = (prior if prior is not None else init_world_T_object).copy()
        if len(sdf_pts) < self.min_points:
            return self._reject(
                fallback, info, f"too few points ({len(sdf_pts)} < {self.min_points})"
            )
        fn, pts, weights = stack_terms(sdf_fn, sdf_pts, sdf_weights, terms)
        info["term_rows"] = len(pts) - len(sdf_pts)
        prior_error = self._prior_error(prior)
        start_pose = invert_pose(np.asarray(init_world_T_object, dtype=np.float64))
        start = self._evaluate(fn, start_pose, pts, weights, prior_error)
        if not (torch.isfinite(start.r).all() and torch.isfinite(start.g).all()):
            return self._reject(fallback, info, "diverged (non-finite SDF at the start)")
        n = len(sdf_pts)
        info["initial_rms_mm"] = fit_check.rms_mm(start.r[:n], sdf_weights)
        best = self._minimise(fn, start, pts, weights, prior_error, info)
        info["final_rms_mm"] = fit_check.rms_mm(best.r[:n], sdf_weights)
        info["cost"] = best.cost
        result = invert_pose(best.obj_T_world)
        reason = divergence(
            result, fallback, self.max_motion_m, self.max_motion_rad
        ) or self._misfit(best, n, weights, info)
        if reason:
            return self._reject(fallback, info, reason)
        return result, info

    def _reject(self, fallback: np.ndarray, info: dict, reason: str) -> tuple[np.ndarray, dict]:
        info["skipped"] = reason
        log.debug("pose tracking solve failed: %s", reason)
        return fallback, info

    def _misfit(self, best: _Linearisation, n: int, weights: Tensor, info: dict) -> str | None:
        """Why the solution does not fit the frame (fit_check.py; None: it does): the
        inlier share of the first `n` (SDF) rows, the conditioning of all rows (colour rows
        see turns the SDF rows cannot).

        An ill-conditioned solve is rejected only without a prior: with one, the prior
        holds the unseen directions at the prediction (a sphere's spin) while the points
        fix the rest, so the frame counts as tracked and info["degenerate"] says so.
        """
        info["inlier_share"] = inlier_share(best.r[:n], weights[:n], self.inlier_m)
        info["conditioning"] = conditioning(best.q, best.g, weights, self.rotation_scale)
        info["degenerate"] = not info["conditioning"] >= self.min_conditioning
        held_by_prior = best.err is not None
        return fit_failure(
            info["inlier_share"],
            info["conditioning"],
            self.min_inlier_share,
            0.0 if held_by_prior else self.min_conditioning,
        )
