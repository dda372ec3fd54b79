"""The field's two heads: SDF from hash-grid features, material logits from SH + x + z(x).

The material branch adds a hash grid of its own (`model.material.grid_levels`, 4 by
default; 0 is the paper's branch): local features that only labelled touches train, so a
narrow band or a small patch can take its own label where SH(direction), x and z(x)
would blend it with its neighbours.
Where no touch reached, the grid's features stay near their (tiny) initial values and the
prediction falls back on SH, x and z(x).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from neuralfeels_sem.fields.hash_grid import HashGridConfig, HashGridEncoding
from neuralfeels_sem.fields.mlp import MLP
from neuralfeels_sem.fields.spherical_harmonics import MAX_DEGREE, SphericalHarmonicsEncoding


@dataclass
class SdfHeadConfig:
    """`model.sdf`: the SDF MLP on the hash-grid features."""

    hidden_dim: int = 64
    num_layers: int = 2

    def __post_init__(self) -> None:
        if self.hidden_dim < 1:
            raise ValueError(f"model.sdf.hidden_dim={self.hidden_dim} must be >= 1")
        if self.num_layers < 1:
            raise ValueError(f"model.sdf.num_layers={self.num_layers} must be >= 1")


@dataclass
class MaterialHeadConfig:
    """`model.material`: the material branch g([SH(dir) || x || z(x)])."""

    # Concatenate z(x), the SDF MLP's last hidden features, to the material input.
    concat_sdf_features: bool = True
    # Concatenate the normalised position x (the paper's g([x || z(x)])).
    include_position: bool = True
    # Highest SH band of the direction from the object centre: 3 -> 16 coefficients.
    sh_degree: int = 3
    hidden_dim: int = 64
    num_layers: int = 1
    # Whether the material loss may move the SDF branch through z(x). Off by default:
    # sparse touch labels should not bend the geometry.
    backprop_to_sdf: bool = False
    # A hash grid of the material branch's own (0 levels: none, the paper's branch), with
    # 2 features per level; its finest cell is about 2 * bound / (base * scale^(levels-1)).
    # 4 levels: on the development objects of object=random it lifted mean-class matching
    # more than any other lever (docs/field_and_mapper.md, the material branch).
    grid_levels: int = 4
    grid_base_resolution: int = 8
    grid_per_level_scale: float = 1.5
    grid_log2_table_size: int = 16

    def __post_init__(self) -> None:
        if not 0 <= self.sh_degree <= MAX_DEGREE:
            raise ValueError(
                f"model.material.sh_degree={self.sh_degree} must be in [0, {MAX_DEGREE}]"
            )
        if self.hidden_dim < 1:
            raise ValueError(f"model.material.hidden_dim={self.hidden_dim} must be >= 1")
        if self.num_layers < 1:
            raise ValueError(f"model.material.num_layers={self.num_layers} must be >= 1")
        if self.grid_levels < 0:
            raise ValueError(
                f"model.material.grid_levels={self.grid_levels} must be >= 0 (0: no material grid)"
            )
        material_grid_config(self, sparse_grad=True)  # its ranges, as model.material.grid_*


def material_grid_config(config: MaterialHeadConfig, sparse_grad: bool) -> HashGridConfig | None:
    """The material grid's HashGridConfig (None without one); `sparse_grad` follows
    model.encoding's. Every grid setting is read and checked, with or without a grid."""
    try:
        grid = HashGridConfig(
            num_levels=max(config.grid_levels, 1),
            features_per_level=2,
            base_resolution=config.grid_base_resolution,
            per_level_scale=config.grid_per_level_scale,
            log2_table_size=config.grid_log2_table_size,
            sparse_grad=sparse_grad,
        )
    except ValueError as exc:
        raise ValueError(str(exc).replace("model.encoding.", "model.material.grid_")) from None
    return grid if config.grid_levels > 0 else None


class SdfHead(nn.Module):
    """Encoding features -> (signed distance in normalised units (N,), hidden z(x) (N, H))."""

    def __init__(self, in_dim: int, config: SdfHeadConfig) -> None:
        super().__init__()
        self.mlp = MLP(in_dim, config.hidden_dim, config.num_layers, 1)

    @property
    def hidden_dim(self) -> int:
        return self.mlp.hidden_dim

    def forward(self, features: Tensor) -> tuple[Tensor, Tensor]:
        out, hidden = self.mlp.forward_with_hidden(features)
        return out.squeeze(-1), hidden


class MaterialHead(nn.Module):
    """g([SH(direction) || x || z(x) || grid(x)]) -> class logits (N, num_classes).

    The direction is from the object centre; x is the normalised position in [-1, 1]^3;
    z(x) (the SDF MLP's last hidden features) is used when `sdf_feature_dim > 0` (the
    field passes the SDF head's width when `config.concat_sdf_features`, else 0); grid(x),
    the material grid's features, when `config.grid_levels > 0`.
    """

    def __init__(
        self,
        num_classes: int,
        sdf_feature_dim: int,
        config: MaterialHeadConfig,
        sparse_grad: bool = True,
    ) -> None:
        """`sparse_grad`: row-sparse gradients for the material grid (as model.encoding's)."""
        super().__init__()
        if num_classes < 2:
            raise ValueError(f"num_classes={num_classes} must be >= 2")
        if sdf_feature_dim < 0:
            raise ValueError(f"sdf_feature_dim={sdf_feature_dim} must be >= 0")
        self.sh = SphericalHarmonicsEncoding(config.sh_degree)
        self.include_position = config.include_position
        self.sdf_feature_dim = sdf_feature_dim
        grid_config = material_grid_config(config, sparse_grad)
        self.grid = HashGridEncoding(grid_config) if grid_config is not None else None
        grid_dim = self.grid.out_dim if self.grid is not None else 0
        in_dim = (
            self.sh.out_dim + (3 if config.include_position else 0) + sdf_feature_dim + grid_dim
        )
        self.mlp = MLP(in_dim, config.hidden_dim, config.num_layers, num_classes)
        self.num_classes = num_classes

    def forward(self, x_normalised: Tensor, sdf_features: Tensor | None = None) -> Tensor:
        parts = [self.sh(x_normalised)]
        if self.include_position:
            parts.append(x_normalised)
        if self.sdf_feature_dim > 0:
            if sdf_features is None or sdf_features.shape != (
                x_normalised.shape[0],
                self.sdf_feature_dim,
            ):
                got = None if sdf_features is None else tuple(sdf_features.shape)
                raise ValueError(
                    f"sdf_features must have shape (N, {self.sdf_feature_dim}), got {got}"
                )
            parts.append(sdf_features)
        if self.grid is not None:
            parts.append(self.grid((x_normalised + 1.0) * 0.5))
        return self.mlp(torch.cat(parts, dim=-1))
