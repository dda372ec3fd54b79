"""What a checkpoint was made from: object (name and content hash), sensor, classes, model.

Resuming a run must continue the same experiment; `check_provenance` refuses a resume
across any of these with one line naming the checkpoint's side and this run's side.
"""

from __future__ import annotations

import hashlib
from dataclasses import MISSING, asdict, dataclass, fields, is_dataclass

import numpy as np

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig
from neuralfeels_sem.utils.nested import flatten

# Keys an older `model` config carried that are not model settings (ignored when comparing,
# so checkpoints written before they were dropped still resume): Hydra's instantiate keys,
# and `bound`, declared (0.1) but always replaced by the one computed from the object.
NOT_MODEL_SETTINGS = ("_target_", "_convert_", "bound")

# Settings whose default changed after they were added: the value a checkpoint written
# before the setting existed ran with (model.material.grid_levels came with default 0, no
# material grid; the default became 4 later).
BEFORE_THEY_EXISTED = {"model.material.grid_levels": 0}


def object_hash(obj) -> str:
    """A short hash of a MaterialObject's mesh, face labels and class names."""
    digest = hashlib.sha256()
    digest.update(np.ascontiguousarray(obj.mesh.vertices, dtype=np.float64).tobytes())
    digest.update(np.ascontiguousarray(obj.mesh.faces, dtype=np.int64).tobytes())
    digest.update(np.ascontiguousarray(obj.face_labels, dtype=np.int64).tobytes())
    digest.update("\0".join(obj.class_names).encode())
    return digest.hexdigest()[:12]


def flat_settings(config: dict, prefix: str = "model") -> dict:
    """`{"sdf": {"hidden_dim": 64}}` -> `{"model.sdf.hidden_dim": 64}`, minus non-settings
    (a key named in NOT_MODEL_SETTINGS at any depth, with everything under it)."""
    return {
        key: value
        for key, value in flatten(config, prefix).items()
        if not set(key[len(prefix) + 1 :].split(".")) & set(NOT_MODEL_SETTINGS)
    }


@dataclass(frozen=True)
class Provenance:
    object_name: str
    object_hash: str
    sensor: str
    classes: tuple[str, ...]
    model: dict  # the composed model config (plain values)

    def to_dict(self) -> dict:
        data = asdict(self)
        data["classes"] = list(self.classes)
        return data

    @classmethod
    def from_dict(cls, data: dict) -> Provenance:
        return cls(
            object_name=str(data["object_name"]),
            object_hash=str(data["object_hash"]),
            sensor=str(data["sensor"]),
            classes=tuple(data["classes"]),
            model=dict(data["model"]),
        )


def _declared_defaults(cls) -> dict:
    """A config dataclass's declared defaults, nested, without constructing it (the model
    config has required keys such as num_classes)."""
    out = {}
    for f in fields(cls):
        if f.default_factory is not MISSING:
            value = f.default_factory()
            out[f.name] = asdict(value) if is_dataclass(value) else value
        elif f.default is not MISSING:
            out[f.name] = f.default
    return out


def _default_settings() -> dict:
    """What a setting missing from an older checkpoint's config ran with."""
    return flat_settings(_declared_defaults(SemanticFieldConfig)) | BEFORE_THEY_EXISTED


def comparable_settings(saved: dict, current: dict) -> tuple[dict, dict]:
    """Both model configs flattened; a setting added after `saved` was written takes there
    the value that kept the behaviour from before it existed (its default when added), so
    older checkpoints of an unchanged model still resume."""
    saved_flat, current_flat = flat_settings(saved), flat_settings(current)
    defaults = _default_settings()
    added = {k: defaults[k] for k in current_flat if k not in saved_flat and k in defaults}
    return {**added, **saved_flat}, current_flat


def _differing_keys(saved_flat: dict, current_flat: dict) -> list[str]:
    return sorted(
        k for k in set(saved_flat) | set(current_flat) if saved_flat.get(k) != current_flat.get(k)
    )


def differing_settings(saved: dict, current: dict) -> list[str]:
    """The flat keys (`model.a.b`) whose values differ between two model configs."""
    return _differing_keys(*comparable_settings(saved, current))


def _model_difference(saved: dict, current: dict) -> str | None:
    """'model.a.b: 64 there, 32 here; ...' for the settings that differ, or None."""
    saved_flat, current_flat = comparable_settings(saved, current)
    keys = _differing_keys(saved_flat, current_flat)
    if not keys:
        return None
    shown = [
        f"{k}: {saved_flat.get(k, 'unset')} there, {current_flat.get(k, 'unset')} here"
        for k in keys[:4]
    ]
    more = f" and {len(keys) - 4} more" if len(keys) > 4 else ""
    return "; ".join(shown) + more


def check_provenance(saved: Provenance, current: Provenance, path: str) -> None:
    """Raise ConfigError (one line, both sides named) unless `current` continues `saved`."""
    prefix = f"mapping.resume={path}: checkpoint is"
    saved_object = f"object {saved.object_name} (hash {saved.object_hash})"
    current_object = f"{current.object_name} (hash {current.object_hash})"
    if saved.object_name != current.object_name:
        raise ConfigError(
            f"{prefix} of {saved_object}, this run is {current_object}: "
            f"resume with object={saved.object_name} or start a new run"
        )
    if saved.sensor != current.sensor:
        raise ConfigError(
            f"{prefix} of sensor {saved.sensor}, this run is {current.sensor}: "
            f"resume with sensor={saved.sensor} or start a new run"
        )
    # Before the hash: the object's labels index the classes, so its hash changes with them.
    if saved.classes != current.classes:
        raise ConfigError(
            f"{prefix} of classes [{','.join(saved.classes)}], this run has "
            f"[{','.join(current.classes)}]: resume with materials=[{','.join(saved.classes)}] "
            "or start a new run"
        )
    if saved.object_hash != current.object_hash:
        raise ConfigError(
            f"{prefix} of {saved_object}, this run is {current_object}: "
            "its mesh or labels changed since the checkpoint; start a new run"
        )
    difference = _model_difference(saved.model, current.model)
    if difference:
        raise ConfigError(
            f"{prefix} of a different model ({difference}): "
            "resume with the checkpoint's model settings or start a new run"
        )
