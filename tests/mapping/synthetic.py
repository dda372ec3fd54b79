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


def small_field(concat: bool = True, log2_table_size: int = 15) -> torch.nn.Module:
    """The real SemanticField, with a small hash table (sparse gradients: FieldAdam) for fast CPU tests."""
    from neuralfeels_sem.configs.model import HashGridConfig, MaterialHeadConfig
    from neuralfeels_sem.fields.semantic_field import SemanticField

    return SemanticField(
        num_classes=2,
        bound=0.08,
        encoding=HashGridConfig(log2_table_size=log2_table_size, sparse_grad=True),
        material=MaterialHeadConfig(concat_sdf_features=concat),
    )
