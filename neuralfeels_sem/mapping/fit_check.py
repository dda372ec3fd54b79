"""Whether a tracked pose fits its frame: the checks a solve must pass to count as tracked.

A Levenberg-Marquardt solve always returns a pose; it is only worth mapping with when the
points it aligned actually sit on the surface and pin all six degrees of freedom. Two
measures decide (thresholds in TrackerConfig, docs/pose.md):

- inlier share: the source-weighted share of points within `inlier_m` of the zero level
  set at the solution. A frame the field cannot explain (a surface not learned yet, a
  wrong basin) leaves most points off the surface.
- conditioning: the smallest over the largest eigenvalue of the data term's Gauss-Newton
  matrix, rotation measured in metres at `rotation_scale`. Near zero, some motion moves
  no point off the surface (a sphere's spin, a plane's slide) and the solve is a guess
  in that direction.

Both are absolute. A third check is relative: a solve that drifts into a wrong basin
can still leave most points near a smooth surface, but fewer than the frames before it
did, and the field, mapped with the drifting poses, then learns to agree. So a solve
whose inlier share falls well below the recent tracked frames' median fails too.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.mapping.se3 import se3_log


def inlier_share(r: Tensor, weights: Tensor, inlier_m: float) -> float:
    """Source-weighted share (0-1) of residuals r (N,) with |r| <= inlier_m."""
    total = float(weights.sum())
    if total <= 0:
        return 0.0
    return float((weights * (r.abs() <= inlier_m)).sum()) / total


def rms_mm(r: Tensor, weights: Tensor) -> float:
    """Weighted root-mean-square residual in millimetres (the solve's report)."""
    return 1e3 * float(torch.sqrt((weights * r * r).sum() / weights.sum()))


def conditioning(q: Tensor, g: Tensor, weights: Tensor, rotation_scale: float) -> float:
    """Smallest / largest eigenvalue (0-1) of the data Gauss-Newton matrix at a pose.

    q: (N, 3) object-frame points, g: (N, 3) SDF gradients there, weights: (N,).
    Rotation is measured as the arc it moves a point at rotation_scale from the origin,
    so both blocks are in metres (rotation columns divided by rotation_scale).
    """
    jac = torch.cat([g, torch.linalg.cross(q, g) / rotation_scale], dim=1)
    h = ((jac * weights[:, None]).T @ jac).numpy()
    eig = np.linalg.eigvalsh(0.5 * (h + h.T))
    if not np.isfinite(eig).all() or eig[-1] <= 0:
        return 0.0
    return float(max(eig[0], 0.0) / eig[-1])


def fit_failure(
    share: float, cond: float, min_inlier_share: float, min_conditioning: float
) -> str | None:
    """Why a solve does not count as tracked (None: it fits)."""
    if not np.isfinite(share) or share < min_inlier_share:
        return f"poor fit (inlier share {share:.2f} < {min_inlier_share})"
    if not np.isfinite(cond) or cond < min_conditioning:
        return f"ill-conditioned (conditioning {cond:.2g} < {min_conditioning:g})"
    return None


def relative_failure(share: float, recent: Sequence[float], max_drop: float) -> str | None:
    """Why a solve fits clearly worse than the recent tracked frames (None: it does not).

    recent: inlier shares of the last tracked frames (no reference while empty).
    """
    if not recent:
        return None
    reference = float(np.median(np.asarray(recent, dtype=np.float64)))
    if share < reference - max_drop:
        return f"poor fit (inlier share {share:.2f}, {reference:.2f} over the last tracked frames)"
    return None


def divergence(
    result: np.ndarray, fallback: np.ndarray, max_motion_m: float, max_motion_rad: float
) -> str | None:
    """Why a solve's `result` counts as diverged (None: it stayed within the caps of its
    distance and turn from `fallback`, the prediction)."""
    if not np.isfinite(result).all():
        return "diverged (non-finite pose)"
    moved = float(np.linalg.norm(result[:3, 3] - fallback[:3, 3]))
    turned = float(np.linalg.norm(se3_log(invert_pose(fallback) @ result)[3:]))
    if moved > max_motion_m or turned > max_motion_rad:
        return f"diverged ({moved:.3g} m, {turned:.3g} rad from the prediction)"
    return None
