"""The field's two heads: SDF from hash-grid features, material logits from SH + x + z(x)."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

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

    def __post_init__(self) -> None:
        if not 0 <= self.sh_degree <= MAX_DEGREE:
            raise ValueError(
                f"model.material.sh_degree={self.sh_degree} must be in [0, {MAX_DEGREE}]"
            )
        if self.hidden_dim < 1:
            raise ValueError(f"model.material.hidden_dim={self.hidden_dim} must be >= 1")
        if self.num_layers < 1:
            raise ValueError(f"model.material.num_layers={self.num_layers} must be >= 1")


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
    """g([SH(direction) || x || z(x)]) -> class logits (N, num_classes).

    The direction is from the object centre; x is the normalised position in [-1, 1]^3;
    z(x) (the SDF MLP's last hidden features) is used when `sdf_feature_dim > 0` (the
    field passes the SDF head's width when `config.concat_sdf_features`, else 0).
    """

    def __init__(self, num_classes: int, sdf_feature_dim: int, config: MaterialHeadConfig) -> None:
        super().__init__()
        if num_classes < 2:
            raise ValueError(f"num_classes={num_classes} must be >= 2")
        if sdf_feature_dim < 0:
            raise ValueError(f"sdf_feature_dim={sdf_feature_dim} must be >= 0")
        self.sh = SphericalHarmonicsEncoding(config.sh_degree)
        self.include_position = config.include_position
        self.sdf_feature_dim = sdf_feature_dim
        in_dim = self.sh.out_dim + (3 if config.include_position else 0) + sdf_feature_dim
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
        return self.mlp(torch.cat(parts, dim=-1))
