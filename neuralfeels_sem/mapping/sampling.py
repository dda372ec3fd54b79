"""Training samples along sensor rays, in the object frame.

A ray ends at an observed surface point p and arrives along the unit direction d (from the
camera centre, or along a DIGIT's +z axis). Samples x = p - s * d are drawn at signed
distances s in front of the surface (s > 0, outside the object) and behind it (s < 0):
- the surface itself (s = 0),
- `band` samples with |s| <= truncation (the truncated-SDF band),
- `free` samples with truncation < s <= min(free_range, ray length) (free space).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class RaySamples:
    """Flattened samples of R rays with K samples each (N = R * K)."""

    x: torch.Tensor  # (N, 3) sample positions
    s: torch.Tensor  # (N,) signed distance along the ray to the surface point, > 0 in front
    free: torch.Tensor  # (N,) bool, True for free-space samples
    ray: torch.Tensor  # (N,) long, index of the sample's ray
    surface: torch.Tensor  # (R, 3) the rays' surface points

    def __len__(self) -> int:
        return int(self.x.shape[0])


def sample_along_rays(
    surface: torch.Tensor,
    direction: torch.Tensor,
    ray_length: torch.Tensor,
    band_samples: int,
    free_samples: int,
    truncation: float,
    free_range: float,
    generator: torch.Generator,
) -> RaySamples:
    """Surface, band and free-space samples for each ray (see module docstring).

    surface (R, 3), direction (R, 3) unit vectors toward the surface, ray_length (R,) the
    distance from the sensor to the surface (free samples never go behind the sensor).
    """
    if surface.ndim != 2 or surface.shape[1] != 3 or direction.shape != surface.shape:
        raise ValueError(
            f"surface and direction must be (R, 3), got {tuple(surface.shape)}, {tuple(direction.shape)}"
        )
    if ray_length.shape != surface.shape[:1]:
        raise ValueError(f"ray_length must be (R,), got {tuple(ray_length.shape)}")
    if truncation <= 0 or free_range < truncation:
        raise ValueError(f"need 0 < truncation ({truncation}) <= free_range ({free_range})")
    r = surface.shape[0]
    dev, dt = surface.device, surface.dtype

    def uniform(shape: tuple[int, ...]) -> torch.Tensor:
        return torch.rand(shape, generator=generator, dtype=dt).to(dev)

    band = (2.0 * uniform((r, band_samples)) - 1.0) * truncation
    far = torch.clamp(ray_length, max=free_range).clamp_min(truncation).unsqueeze(1)
    free = truncation + uniform((r, free_samples)) * (far - truncation)
    s = torch.cat([torch.zeros(r, 1, device=dev, dtype=dt), band, free], dim=1)  # (R, K)
    k = s.shape[1]
    x = surface.unsqueeze(1) - s.unsqueeze(2) * direction.unsqueeze(1)
    is_free = torch.zeros(r, k, dtype=torch.bool, device=dev)
    is_free[:, 1 + band_samples :] = True
    ray = torch.arange(r, device=dev).unsqueeze(1).expand(r, k)
    return RaySamples(
        x=x.reshape(-1, 3),
        s=s.reshape(-1),
        free=is_free.reshape(-1),
        ray=ray.reshape(-1),
        surface=surface,
    )


def random_indices(
    n_total: int, n_draw: int, generator: torch.Generator, device: torch.device
) -> torch.Tensor:
    """n_draw indices in [0, n_total), uniform with replacement (empty when n_total == 0)."""
    if n_total == 0 or n_draw == 0:
        return torch.zeros(0, dtype=torch.long, device=device)
    return torch.randint(n_total, (n_draw,), generator=generator).to(device)


def label_groups(labels: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(order, starts, counts) of labels (N,): the indices grouped by label, and where each
    label present starts in `order` and how many points it has (CPU)."""
    _, inverse, counts = torch.unique(labels.cpu(), return_inverse=True, return_counts=True)
    order = torch.argsort(inverse, stable=True)
    return order, torch.cumsum(counts, 0) - counts, counts


def balanced_indices(
    groups: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    n_draw: int,
    generator: torch.Generator,
    device: torch.device,
    power: float = 0.0,
) -> torch.Tensor:
    """n_draw indices with replacement: a label of `groups` (label_groups) drawn with
    probability proportional to its point count to the `power` (0: every label equally
    likely; 1: as uniform over all points), then uniform among its points; empty when
    there are no points."""
    order, starts, counts = groups
    if len(order) == 0 or n_draw == 0:
        return torch.zeros(0, dtype=torch.long, device=device)
    if power == 0.0:
        which = torch.randint(len(counts), (n_draw,), generator=generator)
    else:
        share = counts.double() ** power
        which = torch.multinomial(share, n_draw, replacement=True, generator=generator)
    within = (torch.rand(n_draw, generator=generator) * counts[which]).long()
    within = torch.minimum(within, counts[which] - 1)  # float rounding must not reach the next
    return order[starts[which] + within].to(device)


def subsample(
    n_total: int, n_keep: int, generator: torch.Generator, replace_if_short: bool
) -> torch.Tensor:
    """Indices of a random subset of size n_keep (CPU); with replacement when n_total < n_keep
    and `replace_if_short`, otherwise all indices then."""
    if n_total == 0:
        return torch.zeros(0, dtype=torch.long)
    if n_total >= n_keep:
        return torch.randperm(n_total, generator=generator)[:n_keep]
    if replace_if_short:
        return torch.randint(n_total, (n_keep,), generator=generator)
    return torch.arange(n_total)
