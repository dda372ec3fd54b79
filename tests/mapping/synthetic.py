"""Test helpers: the analytic sphere scene (package module) and a small real field."""

from __future__ import annotations

import torch

from neuralfeels_sem.mapping.sphere_scene import (  # noqa: F401  (re-exported for tests)
    RADIUS,
    camera_reading,
    digit_reading,
    fibonacci_directions,
    object_pose,
    sphere_depth,
    sphere_frames,
    sphere_surface,
    true_label,
)


def small_field(
    concat: bool = True, log2_table_size: int = 15, material_grid_levels: int | None = None
) -> torch.nn.Module:
    """The real SemanticField, with a small hash table (sparse gradients: FieldAdam) for fast
    CPU tests; the material grid as the command line's unless `material_grid_levels`."""
    from neuralfeels_sem.fields.hash_grid import HashGridConfig
    from neuralfeels_sem.fields.heads import MaterialHeadConfig
    from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig

    config = SemanticFieldConfig(
        num_classes=2,
        encoding=HashGridConfig(log2_table_size=log2_table_size, sparse_grad=True),
        material=MaterialHeadConfig(
            concat_sdf_features=concat,
            grid_levels=MaterialHeadConfig.grid_levels
            if material_grid_levels is None
            else material_grid_levels,
        ),
    )
    return SemanticField(config, bound=0.08)


def small_mapper(field: torch.nn.Module | None = None, lr: float = 3e-3, **settings):
    """An OnlineMapper with the command line's settings (MapperConfig defaults) except
    `settings`, on `field` (default: small_field()), with FieldAdam at `lr`, on the CPU.

    The synthetic frames carry exact masks and contact depths and no tactile images, so
    the mapper takes them as given (camera_mask=gt, tactile depth gt) unless `settings`
    say otherwise: these tests are of the mapper, perception has its own."""
    import functools

    from neuralfeels_sem.fields.optim import FieldAdam
    from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
    from neuralfeels_sem.perception.tactile_depth import TactileDepthConfig

    given = {"camera_mask": "gt", "tactile_depth": TactileDepthConfig(source="gt")}
    config = MapperConfig(**{"num_classes": 2, **given, **settings})
    field = small_field() if field is None else field
    return OnlineMapper(config, field, functools.partial(FieldAdam, lr=lr), "cpu")
