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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np
import torch
from torch import Tensor

from neuralfeels_sem.core.geometry import check_pose, invert_pose, orthonormalize_pose

log = logging.getLogger(__name__)

RobustLoss = Literal["huber", "cauchy"]
ROBUST_LOSSES = get_args(RobustLoss)


@dataclass
class TrackerConfig:
    """`mapping.tracker`: PoseTracker's settings (used when mapping.pose=track*).

    max_step_m, max_step_rad: the largest translation / rotation one LM step may make;
        a larger step is treated like a failed one (more damping). Far from the surface
        the field's SDF is clamped and flat, and an undamped step once threw the pose
        10^27 m away.
    max_motion_m: a result further than this from the starting (or predicted) pose is
        rejected as diverged and the prediction kept.
    prior_weight: weight of the squared distance to the predicted pose, relative to the
        mean squared SDF residual (translation in metres, rotation times rotation_scale).
    source_weights: per-point weight by source ("camera", or a finger name; "tactile"
        applies to every finger); 0 drops that modality from tracking.
    """

    iterations: int = 15  # Levenberg-Marquardt iterations per frame
    # A RobustLoss; typed `str` because OmegaConf 2.3 rejects Literal annotations.
    robust_loss: str = "cauchy"
    robust_scale: float = 0.001  # metres where the robust loss stops being quadratic
    min_points: int = 50  # fewer points: keep the predicted pose (>= 6 pose unknowns)
    damping: float = 1.0e-3  # initial LM damping
    prior_weight: float = 0.01  # pull toward the constant-velocity prediction
    rotation_scale: float = 0.05  # metres per radian in the prior (about the object radius)
    max_step_m: float = 0.01
    max_step_rad: float = 0.2
    max_motion_m: float = 0.03
    max_points_per_source: int = 1000  # camera, and each finger
    source_weights: dict[str, float] = field(
        default_factory=lambda: {"camera": 1.0, "tactile": 1.0}
    )
    tolerance: float = 1.0e-7  # stop when a step changes the pose less than this
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
            "max_step_m", "max_step_rad", "max_motion_m",
        )  # fmt: skip
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"mapping.tracker.{name}={getattr(self, name)} must be > 0")
        if self.prior_weight < 0:
            raise ValueError(f"mapping.tracker.prior_weight={self.prior_weight} must be >= 0")
        if self.min_points < 6 or self.max_points_per_source < 1:
            raise ValueError(
                f"mapping.tracker needs min_points >= 6 ({self.min_points}; six pose unknowns) "
                f"and max_points_per_source >= 1 ({self.max_points_per_source})"
            )
        if any(w < 0 for w in self.source_weights.values()):
            raise ValueError(
                f"mapping.tracker.source_weights={dict(self.source_weights)} must be >= 0"
            )


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """xi = (v, w) (6,) -> 4x4 rigid transform (Rodrigues, exact for any angle)."""
    xi = np.asarray(xi, dtype=np.float64)
    if xi.shape != (6,):
        raise ValueError(f"se3_exp needs a (6,) vector, got {xi.shape}")
    v, w = xi[:3], xi[3:]
    theta = float(np.linalg.norm(w))
    k = _skew(w)
    if theta < 1e-8:
        rot = np.eye(3) + k
        jac = np.eye(3) + 0.5 * k
    else:
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / theta**2
        c = (theta - np.sin(theta)) / theta**3
        rot = np.eye(3) + a * k + b * (k @ k)
        jac = np.eye(3) + b * k + c * (k @ k)
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = jac @ v
    return out


def se3_log(pose: np.ndarray) -> np.ndarray:
    """4x4 rigid transform -> xi = (v, w) (6,), the inverse of se3_exp (angles below pi)."""
    check_pose(pose, "pose")
    rot = pose[:3, :3]
    cos = np.clip((np.trace(rot) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos))
    vee = np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    if theta < 1e-8:
        w = 0.5 * vee
    else:
        w = theta / (2.0 * np.sin(theta)) * vee
    k = _skew(w)
    if theta < 1e-8:
        jac_inv = np.eye(3) - 0.5 * k
    else:
        half = 0.5 * theta
        jac_inv = np.eye(3) - 0.5 * k + (1.0 - half / np.tan(half)) / theta**2 * (k @ k)
    return np.concatenate([jac_inv @ pose[:3, 3], w])


def constant_velocity(poses: list[np.ndarray]) -> np.ndarray:
    """Next world_T_object if the last body-frame motion repeats (the last pose when alone)."""
    if not poses:
        raise ValueError("constant_velocity needs at least one pose")
    if len(poses) == 1:
        return poses[-1].copy()
    step = invert_pose(poses[-2]) @ poses[-1]
    return orthonormalize_pose(poses[-1] @ step)


def robust_weights(r: Tensor, loss: str, scale: float) -> tuple[Tensor, Tensor]:
    """IRLS weights w(r) and the loss rho(r) (both (N,)), with rho ~ r^2 near zero."""
    a = r.abs()
    if loss == "huber":
        w = torch.where(a <= scale, torch.ones_like(a), scale / a.clamp_min(1e-12))
        rho = torch.where(a <= scale, r * r, 2.0 * scale * a - scale * scale)
    elif loss == "cauchy":
        z = (r / scale) ** 2
        w = 1.0 / (1.0 + z)
        rho = scale * scale * torch.log1p(z)
    else:
        raise ValueError(f"robust loss {loss!r} is not one of {ROBUST_LOSSES}")
    return w, rho


@dataclass
class _Linearisation:
    """The alignment at one pose: object-frame points q, residuals r, SDF gradients g,
    the prior error, the cost and the robust weights."""

    obj_T_world: np.ndarray
    q: Tensor
    r: Tensor
    g: Tensor
    err: np.ndarray | None
    cost: float
    w: Tensor


def _rms_mm(r: Tensor, weights: Tensor) -> float:
    return 1e3 * float(torch.sqrt((weights * r * r).sum() / weights.sum()))


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
        self.source_weights = dict(config.source_weights)
        self.tolerance = float(config.tolerance)
        self.max_step_m = float(config.max_step_m)
        self.max_step_rad = float(config.max_step_rad)
        self.max_motion_m = float(config.max_motion_m)
        self.generator = torch.Generator().manual_seed(int(config.seed))

    def source_weight(self, source: str) -> float:
        if source in self.source_weights:
            return float(self.source_weights[source])
        default = "camera" if source == "camera" else "tactile"
        return float(self.source_weights.get(default, 1.0))

    def _gather(self, points_world: Mapping[str, Tensor]) -> tuple[Tensor, Tensor]:
        """All usable points (N, 3) float64 and their per-point source weights (N,)."""
        pts, weights = [], []
        for source, p in points_world.items():
            p = torch.as_tensor(p, dtype=torch.float64)
            if p.ndim != 2 or p.shape[1] != 3:
                raise ValueError(f"points of {source} must have shape (N, 3), got {tuple(p.shape)}")
            w = self.source_weight(source)
            p = p[torch.isfinite(p).all(dim=1)]
            if w == 0 or len(p) == 0:
                continue
            if len(p) > self.max_points_per_source:
                keep = torch.randperm(len(p), generator=self.generator)[
                    : self.max_points_per_source
                ]
                p = p[keep]
            pts.append(p)
            weights.append(torch.full((len(p),), w, dtype=torch.float64))
        if not pts:
            return torch.zeros((0, 3), dtype=torch.float64), torch.zeros(0, dtype=torch.float64)
        return torch.cat(pts), torch.cat(weights)

    def _linearise(
        self, sdf_fn: Callable[[Tensor], Tensor], object_T_world: np.ndarray, pts: Tensor
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Object-frame points q, residuals r = sdf(q) and gradients d sdf / d q (float64)."""
        t = torch.as_tensor(object_T_world, dtype=torch.float64)
        q = pts @ t[:3, :3].T + t[:3, 3]
        with torch.enable_grad():
            x = q.to(torch.float32).requires_grad_(True)
            sdf = sdf_fn(x)
            if sdf.shape != (len(x),):
                sdf = sdf.reshape(len(x))
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
    ) -> _Linearisation:
        q, r, g = self._linearise(sdf_fn, obj_T_world, pts)
        err = prior_error(obj_T_world)
        cost, w = self._cost(r, weights, err)
        return _Linearisation(obj_T_world, q, r, g, err, cost, w)

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
        """Levenberg-Marquardt from `cur`; counts iterations and evaluations in `info`."""
        mu = self.damping
        prior_h = self.prior_weight * np.diag(self._prior_scale() ** 2)
        for it in range(self.iterations):
            info["iterations"] = it + 1
            h, b = self._normal_equations(cur, weights, prior_h)
            step = None
            while mu < 1e8:
                lhs = h + mu * np.diag(np.diag(h) + 1e-12)
                delta = -np.linalg.solve(lhs, b)
                too_far = np.linalg.norm(delta[:3]) > self.max_step_m
                if too_far or np.linalg.norm(delta[3:]) > self.max_step_rad:
                    mu *= 10.0
                    continue
                cand = self._evaluate(
                    sdf_fn, se3_exp(delta) @ cur.obj_T_world, pts, weights, prior_error
                )
                info["evaluations"] += 1
                if cand.cost <= cur.cost:
                    step, cur = delta, cand
                    mu = max(mu / 10.0, 1e-9)
                    break
                mu *= 10.0
            if step is None or np.linalg.norm(step) < self.tolerance:
                break
        return cur

    def track(
        self,
        points_world: Mapping[str, Tensor | np.ndarray],
        sdf_fn: Callable[[Tensor], Tensor],
        init_world_T_object: np.ndarray,
        prior: np.ndarray | None = None,
    ) -> tuple[np.ndarray, dict]:
        """world_T_object that puts the points on sdf_fn's zero level set, and a report.

        points_world: (N, 3) world-frame points per source. sdf_fn: (N, 3) float32
        object-frame points -> (N,) signed distances, differentiable in its input.
        prior: the predicted world_T_object the prior pulls toward (None: no prior).
        With fewer than `min_points` points the prior (else the initial pose) comes back
        unchanged with info["skipped"] set.
        """
        check_pose(init_world_T_object, "init_world_T_object")
        if prior is not None:
            check_pose(prior, "prior")
        pts, weights = self._gather(points_world)
        info: dict = {"points": len(pts), "iterations": 0, "evaluations": 0, "skipped": None}
        fallback = (prior if prior is not None else init_world_T_object).copy()
        if len(pts) < self.min_points:
            info["skipped"] = f"too few points ({len(pts)} < {self.min_points})"
            log.warning("pose tracking kept the predicted pose: %s", info["skipped"])
            return fallback, info
        prior_error = self._prior_error(prior)
        start = self._evaluate(
            sdf_fn,
            invert_pose(np.asarray(init_world_T_object, dtype=np.float64)),
            pts,
            weights,
            prior_error,
        )
        info["initial_rms_mm"] = _rms_mm(start.r, weights)
        best = self._minimise(sdf_fn, start, pts, weights, prior_error, info)
        info["final_rms_mm"] = _rms_mm(best.r, weights)
        info["cost"] = best.cost
        result = invert_pose(best.obj_T_world)
        moved = float(np.linalg.norm(result[:3, 3] - fallback[:3, 3]))
        if not np.isfinite(result).all() or moved > self.max_motion_m:
            info["skipped"] = f"diverged ({moved:.3g} m from the prediction)"
            log.warning("pose tracking kept the predicted pose: %s", info["skipped"])
            return fallback, info
        return result, info
