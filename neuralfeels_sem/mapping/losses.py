"""Losses of the online mapper (iSDF / NeuralFeels style), all returning per-sample values.

Signed distances are in metres. Bounds: for a sample at signed distance s along its ray,
|s| and the distance to the nearest observed surface point of the batch are both upper
bounds on |SDF| (iSDF's batch bound); the sign is + in front of the surface, - behind.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from scipy.spatial import cKDTree


def batch_bound(
    x: torch.Tensor, s: torch.Tensor, surface: torch.Tensor, chunk: int = 8192
) -> torch.Tensor:
    """Upper bound on |SDF(x)|: min(|s|, distance to the nearest point of `surface`)."""
    if x.ndim != 2 or x.shape[1] != 3 or surface.ndim != 2 or surface.shape[1] != 3:
        raise ValueError(
            f"x and surface must be (N, 3), got {tuple(x.shape)}, {tuple(surface.shape)}"
        )
    if s.shape != x.shape[:1]:
        raise ValueError(f"s must be (N,), got {tuple(s.shape)}")
    if x.device.type == "cpu" and len(surface):
        # A KD-tree over the batch's few hundred surface points: a third of the brute
        # force's time on a CPU mapper step, and exact distances (cdist's matrix form
        # rounds them to float32 products).
        found, _ = cKDTree(surface.detach().double().numpy()).query(x.detach().double().numpy())
        nearest = torch.from_numpy(found).to(x.dtype)
    else:
        nearest = torch.cat([torch.cdist(xc, surface).min(dim=1).values for xc in x.split(chunk)])
    return torch.minimum(s.abs(), nearest)


def truncated_sdf_loss(sdf: torch.Tensor, s: torch.Tensor, bound: torch.Tensor) -> torch.Tensor:
    """|sdf - sign(s) * bound| for samples inside the truncation band (0 at the surface)."""
    return (sdf - torch.sign(s) * bound).abs()


def freespace_loss(sdf: torch.Tensor, bound: torch.Tensor) -> torch.Tensor:
    """Free-space samples: the SDF must lie in [0, bound]; penalise the distance outside it."""
    return F.relu(-sdf) + F.relu(sdf - bound)


def space_prior_loss(
    sdf: torch.Tensor, sign: torch.Tensor, floor: torch.Tensor | None = None
) -> torch.Tensor:
    """Hinge on the SDF's sign: +1 targets (outside) penalise sdf < floor (0 by default),
    -1 (solid) sdf > 0."""
    if sign.shape != sdf.shape or (floor is not None and floor.shape != sdf.shape):
        shapes = (tuple(sign.shape), None if floor is None else tuple(floor.shape))
        raise ValueError(f"sign and floor {shapes} must match sdf {tuple(sdf.shape)}")
    floor = torch.zeros_like(sdf) if floor is None else torch.where(sign > 0, floor, 0.0)
    return F.relu(floor - sign * sdf)


def eikonal_loss(gradient: torch.Tensor) -> torch.Tensor:
    """(|grad SDF| - 1)^2 per sample."""
    if gradient.ndim != 2 or gradient.shape[1] != 3:
        raise ValueError(f"gradient must be (N, 3), got {tuple(gradient.shape)}")
    return (gradient.norm(dim=1) - 1.0) ** 2


def material_loss(
    logits: torch.Tensor, labels: torch.Tensor, weights: torch.Tensor
) -> torch.Tensor:
    """Cross-entropy against the touch's label, weighted by the classifier's confidence."""
    if logits.ndim != 2 or labels.shape != logits.shape[:1] or weights.shape != labels.shape:
        raise ValueError(
            f"logits (N, C), labels (N,), weights (N,) expected; got {tuple(logits.shape)}, "
            f"{tuple(labels.shape)}, {tuple(weights.shape)}"
        )
    return weights * F.cross_entropy(logits, labels, reduction="none")
