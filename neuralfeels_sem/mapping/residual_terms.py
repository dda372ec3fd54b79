"""The residuals a pose solve minimises: the SDF of the frame's points plus extra terms.

Every term is a function of object-frame points q (one row each) whose gradient in q gives
its Jacobian row [g, q x g] (pose_tracker.py), so all terms share one batched solve: the
rows are stacked, and one combined function evaluates each term on its own rows. Row
weights make each extra term's total weight `weight` times the SDF term's, whatever the
row counts.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
import torch
from torch import Tensor

RobustLoss = Literal["huber", "cauchy"]
ROBUST_LOSSES = get_args(RobustLoss)


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
class ResidualTerm:
    """Rows beyond the SDF's: world points (M, 3), their residual function of object-frame
    points (M, 3) float32 -> (M,), and the term's total weight relative to the SDF term."""

    points_world: np.ndarray
    residuals: Callable[[Tensor], Tensor]
    weight: float
    name: str = "term"

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_world)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"{self.name}: points must have shape (M, 3), got {pts.shape}")
        if not self.weight >= 0:
            raise ValueError(f"{self.name}: weight {self.weight} must be >= 0")


def stack_terms(
    sdf_fn: Callable[[Tensor], Tensor],
    pts: Tensor,
    weights: Tensor,
    terms: Sequence[ResidualTerm],
) -> tuple[Callable[[Tensor], Tensor], Tensor, Tensor]:
    """One residual function over the SDF rows followed by every term's rows, the stacked
    points (float64) and row weights. The SDF rows come first and keep their weights."""
    used = [t for t in terms if t.weight > 0 and len(t.points_world)]
    if not used:
        return sdf_fn, pts, weights
    sdf_total = float(weights.sum())
    blocks, row_weights, counts = [pts], [weights], [len(pts)]
    for term in used:
        p = torch.as_tensor(term.points_world, dtype=torch.float64)
        blocks.append(p)
        row_weights.append(
            torch.full((len(p),), term.weight * sdf_total / len(p), dtype=torch.float64)
        )
        counts.append(len(p))
    fns = [sdf_fn, *(t.residuals for t in used)]

    def stacked(x: Tensor) -> Tensor:
        parts = torch.split(x, counts)
        return torch.cat([fn(part).reshape(len(part)) for fn, part in zip(fns, parts)])

    return stacked, torch.cat(blocks), torch.cat(row_weights)
