"""Schema for conf/model/: the semantic neural field (SDF + material branches).

The nested blocks are dataclasses that `SemanticField` takes directly: the model yaml sets
`_convert_: object`, so Hydra hands them over as instances of these classes, and direct
callers build them by hand (`MaterialHeadConfig(concat_sdf_features=False)`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

# Highest SH band implemented (neuralfeels_sem.fields.spherical_harmonics.MAX_DEGREE); kept
# literal so composing configs does not import torch.
MAX_DEGREE = 3


@dataclass
class HashGridConfig:
    """Multiresolution hash grid; defaults are the paper's except log2_table_size (CPU)."""

    num_levels: int = 16
    features_per_level: int = 2
    base_resolution: int = 16
    per_level_scale: float = 1.3819
    # The paper uses 24; 2^24 rows x 11 hashed levels is 1.5 GB of float32 before Adam.
    log2_table_size: int = 19
    init_scale: float = 1e-4
    # Row-sparse table gradients (needs an optimiser that takes them: FieldAdam).
    sparse_grad: bool = True

    def __post_init__(self) -> None:
        for name in ("num_levels", "features_per_level", "base_resolution"):
            if getattr(self, name) < 1:
                raise ValueError(f"model.encoding.{name}={getattr(self, name)} must be >= 1")
        if self.per_level_scale < 1.0:
            raise ValueError(f"model.encoding.per_level_scale={self.per_level_scale} must be >= 1")
        if not 4 <= self.log2_table_size <= 30:
            raise ValueError(
                f"model.encoding.log2_table_size={self.log2_table_size} must be in [4, 30]"
            )
        if self.init_scale < 0:
            raise ValueError(f"model.encoding.init_scale={self.init_scale} must be >= 0")


@dataclass
class SdfHeadConfig:
    hidden_dim: int = 64
    num_layers: int = 2

    def __post_init__(self) -> None:
        if self.hidden_dim < 1:
            raise ValueError(f"model.sdf.hidden_dim={self.hidden_dim} must be >= 1")
        if self.num_layers < 1:
            raise ValueError(f"model.sdf.num_layers={self.num_layers} must be >= 1")


@dataclass
class MaterialHeadConfig:
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


@dataclass
class SemanticFieldConfig:
    _target_: str = "neuralfeels_sem.fields.semantic_field.SemanticField"
    _convert_: str = "object"
    num_classes: int = MISSING
    # Half-extent (metres) of the cube [-bound, bound]^3 around `center` (object frame).
    bound: float = 0.1
    center: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    encoding: HashGridConfig = field(default_factory=HashGridConfig)
    sdf: SdfHeadConfig = field(default_factory=SdfHeadConfig)
    material: MaterialHeadConfig = field(default_factory=MaterialHeadConfig)

    def __post_init__(self) -> None:
        if self.num_classes < 2:
            raise ValueError(f"model.num_classes={self.num_classes} must be >= 2")
        if self.bound <= 0:
            raise ValueError(f"model.bound={self.bound} must be > 0")
        if len(self.center) != 3:
            raise ValueError(f"model.center={self.center} must have 3 values")


def register(cs) -> None:
    cs.store(group="schema/model", name="semantic_sdf", node=SemanticFieldConfig)
