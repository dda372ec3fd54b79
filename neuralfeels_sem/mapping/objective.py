"""The mapper's objective on one Batch: the weighted sum of its losses (losses.py).

- sdf / freespace: truncated-SDF and free-space losses on the ray samples, each sample
  weighted by its source (camera_weight, tactile_weight), averaged over band samples and
  over free samples;
- space: the space-carving prior's sign hinge (a regulariser for unseen space);
- eikonal: (|grad SDF| - 1)^2 at `eikonal_points` of the ray samples (off at weight 0);
- material: confidence-weighted cross-entropy at labelled touch points.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch
from torch import nn

from neuralfeels_sem.mapping.batch import Batch
from neuralfeels_sem.mapping.losses import (
    batch_bound,
    eikonal_loss,
    freespace_loss,
    material_loss,
    space_prior_loss,
    truncated_sdf_loss,
)
from neuralfeels_sem.mapping.sampling import random_indices

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig

TERMS = ("sdf", "freespace", "space", "eikonal", "material")


class MapperObjective:
    """Loss terms and their weights (MapperConfig's `*_weight` and `eikonal_points`)."""

    def __init__(self, config: MapperConfig, generator: torch.Generator) -> None:
        self.weights = {
            "sdf": config.sdf_weight,
            "freespace": config.freespace_weight,
            "space": config.space_prior_weight,
            "eikonal": config.eikonal_weight,
            "material": config.material_weight,
        }
        self.eikonal_points = config.eikonal_points
        self.generator = generator  # draws the eikonal points

    def uses_eikonal(self, batch: Batch) -> bool:
        return self.weights["eikonal"] > 0 and self.eikonal_points > 0 and bool(batch.rays)

    def losses(
        self, field: nn.Module, batch: Batch, out: dict[str, torch.Tensor]
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor | None]:
        """Each term (a scalar) and the per-sample ray losses (None without rays)."""
        zero = torch.zeros((), device=batch.x.device)
        losses = dict.fromkeys(TERMS, zero)
        n_geo, n_space = batch.num_geometry, len(batch.space_sign)
        per_sample = None
        if batch.rays:
            per_sample = self._ray_losses(batch, out["sdf"][:n_geo], losses)
            if self.uses_eikonal(batch):
                idx = random_indices(n_geo, self.eikonal_points, self.generator, batch.x.device)
                xe = batch.x[idx].detach().requires_grad_(True)
                (grad,) = torch.autograd.grad(field.sdf(xe).sum(), xe, create_graph=True)
                losses["eikonal"] = eikonal_loss(grad).mean()
        if n_space:
            sdf_space = out["sdf"][n_geo : n_geo + n_space]
            losses["space"] = space_prior_loss(
                sdf_space, batch.space_sign, batch.space_floor
            ).mean()
        if len(batch.material_labels):
            # The material rows come last (the field may return logits for them alone).
            logits = out["material_logits"][-len(batch.material_labels) :]
            losses["material"] = material_loss(
                logits, batch.material_labels, batch.material_weights
            ).mean()
        return losses, per_sample

    def _ray_losses(
        self, batch: Batch, sdf: torch.Tensor, losses: dict[str, torch.Tensor]
    ) -> torch.Tensor:
        """Fill losses["sdf"] and ["freespace"]; per-sample weighted loss (N_geo,)."""
        rays = batch.rays
        device = sdf.device
        s = torch.cat([r.s for r, _ in rays])
        free = torch.cat([r.free for r, _ in rays])
        weight = torch.cat([torch.full((len(r),), float(w), device=device) for r, w in rays])
        bound = batch_bound(batch.x[: len(sdf)], s, torch.cat([r.surface for r, _ in rays]))
        per_sample = (
            torch.where(free, freespace_loss(sdf, bound), truncated_sdf_loss(sdf, s, bound))
            * weight
        )
        losses["sdf"] = per_sample[~free].sum() / max(int((~free).sum()), 1)
        losses["freespace"] = per_sample[free].sum() / max(int(free.sum()), 1)
        return per_sample

    def total(self, losses: dict[str, torch.Tensor]) -> torch.Tensor:
        return (
            self.weights["sdf"] * losses["sdf"]
            + self.weights["freespace"] * losses["freespace"]
            + self.weights["space"] * losses["space"]
            + self.weights["eikonal"] * losses["eikonal"]
            + self.weights["material"] * losses["material"]
        )
