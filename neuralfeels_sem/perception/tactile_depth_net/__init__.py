"""The learned tactile depth network (mapping.mapper.tactile_depth.source=net): model,
checkpoint, inference and training on simulator renders (see docs/perception.md)."""

from neuralfeels_sem.perception.tactile_depth_net.predict import (
    SHIPPED_CHECKPOINT,
    DepthNetPredictor,
)

__all__ = ["SHIPPED_CHECKPOINT", "DepthNetPredictor"]
