"""The points a tracking solve aligns: every source's finite world points, each source
capped by a random subset (the SDF batch sets a solve's cost), with per-point weights."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
import torch
from torch import Tensor


def gather_points(
    points_world: Mapping[str, Tensor | np.ndarray],
    weight_of: Callable[[str], float],
    caps: Mapping[str, int],
    default_cap: int,
    generator: torch.Generator,
) -> tuple[Tensor, Tensor]:
    """(N, 3) float64 points of every source with a weight above 0, and their weights (N,).

    caps: the most points kept per named source; any other source keeps `default_cap`.
    """
    pts, weights = [], []
    for source, p in points_world.items():
        p = torch.as_tensor(p, dtype=torch.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points of {source} must have shape (N, 3), got {tuple(p.shape)}")
        w = weight_of(source)
        p = p[torch.isfinite(p).all(dim=1)]
        if w == 0 or len(p) == 0:
            continue
        cap = caps.get(source, default_cap)
        if len(p) > cap:
            p = p[torch.randperm(len(p), generator=generator)[:cap]]
        pts.append(p)
        weights.append(torch.full((len(p),), w, dtype=torch.float64))
    if not pts:
        return torch.zeros((0, 3), dtype=torch.float64), torch.zeros(0, dtype=torch.float64)
    return torch.cat(pts), torch.cat(weights)
