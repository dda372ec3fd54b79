"""Config -> the objects of a mapping run, shared by task=map and task=eval."""

from __future__ import annotations

from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.configs import to_config
from neuralfeels_sem.eval.run_scorer import RunScorer
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig
from neuralfeels_sem.mapping.field_init import build_field
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper

# The field's half-extent is BOUND_MARGIN times the object's bounding radius (computed per
# object, not a setting): the truncation band and free-space samples just outside the
# surface must stay inside the hash grid.
BOUND_MARGIN = 1.15


def build_scorer(cfg: DictConfig, obj) -> RunScorer:
    e = cfg.eval
    return RunScorer(
        obj,
        num_surface_samples=e.num_surface_samples,
        image_views=e.image_views,
        image_size=e.image_size,
        image_elevation_deg=e.image_elevation_deg,
        fscore_thresholds_mm=list(e.fscore_thresholds_mm),
        shape_samples=e.shape_samples,
        mesh_resolution=e.mesh_resolution,
        seed=e.seed,
        mesh_match_tolerance_m=e.mesh_match_tolerance_m,
    )


def build_mapper(cfg: DictConfig, bound: float, device, hand_model=None) -> OnlineMapper:
    """The field (cube half-extent `bound`, from the object) and its online mapper.

    `hand_model` (Sensor.hand_model()) lets mapping.mapper.camera_mask=segment crop to the
    palm's workspace and remove the hand from the camera image.
    """
    # build_field records how the field was initialised: checkpoints then skip the table
    # rows training never reached (mapping/checkpoint_codec.py).
    field = build_field(to_config(SemanticFieldConfig, cfg.model), bound)
    optimizer_factory = instantiate(cfg.mapping.optimizer)  # a partial FieldAdam
    return OnlineMapper(
        to_config(MapperConfig, cfg.mapping.mapper), field, optimizer_factory, device, hand_model
    )


def model_config(cfg: DictConfig) -> dict:
    """What a checkpoint must match to resume: the composed model config."""
    return OmegaConf.to_container(cfg.model, resolve=True)
