"""Checkpoints of an online mapping run: save atomically, load safely, resume exactly.

A checkpoint holds the mapper's full state (field, optimiser, keyframes, touches,
counters, RNG states), the index of the last frame it has seen, a signature of the
field (class and parameter shapes), its provenance (object and its hash, sensor, classes,
model config: mapping/provenance.py) and the caller's `extra` dict of plain values. It is
written to `<path>.tmp` and renamed over `path`, so a run killed mid-write keeps its
previous checkpoint intact; it is read with `torch.load(weights_only=True)`. The hash
tables and their Adam moments, nearly all of its bytes, are stored as
mapping/checkpoint_codec.py says: exact while that fits 40 MB, else compact.
"""

from __future__ import annotations

import copy
import os
import warnings
from pathlib import Path

import torch

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.mapping.checkpoint_codec import INIT_KEY, compress, decode, prepare, take
from neuralfeels_sem.mapping.field_init import adopt_init_state
from neuralfeels_sem.mapping.mapper import OnlineMapper
from neuralfeels_sem.mapping.provenance import Provenance, differing_settings

# 2 added the provenance; version 1 files still load (task=eval) but cannot be resumed.
# 3 packs the hash tables (checkpoint_codec.py); versions 1 and 2 hold them whole and load.
# 4: compact storage also narrows the memory's point clouds (older code must not load it).
FORMAT_VERSION = 4
READABLE_VERSIONS = (1, 2, 3, 4)


def field_signature(mapper: OnlineMapper) -> dict:
    """Field class, class count and parameter shapes: what must match to resume."""
    return {
        "class": type(mapper.field).__qualname__,
        "num_classes": mapper.num_classes,
        "shapes": {k: list(v.shape) for k, v in mapper.field.state_dict().items()},
    }


def save_checkpoint(
    path: str | Path,
    mapper: OnlineMapper,
    frame_index: int,
    extra: dict | None = None,
    model_config: dict | None = None,
    provenance: Provenance | None = None,
    storage: str = "auto",
) -> None:
    """Write `path` atomically. `extra` and `model_config` must hold plain values only;
    `storage`: auto, exact or compact, how the hash tables are stored (checkpoint_codec.py)."""
    write_checkpoint(
        path, take_checkpoint(mapper, frame_index, extra, model_config, provenance, storage)
    )


def prepare_checkpoints(mapper: OnlineMapper) -> None:
    """Do now the one-off work of the first `take_checkpoint` (checkpoint_codec.prepare)."""
    prepare(mapper.field)


def take_checkpoint(
    mapper: OnlineMapper,
    frame_index: int,
    extra: dict | None = None,
    model_config: dict | None = None,
    provenance: Provenance | None = None,
    storage: str = "auto",
) -> dict:
    """A copy of everything the checkpoint holds, taken now; `write_checkpoint` may write it
    from another thread while the mapper trains on (CheckpointWriter)."""
    return {
        "version": FORMAT_VERSION,
        "frame_index": int(frame_index),
        "signature": field_signature(mapper),
        "model_config": copy.deepcopy(model_config),
        "provenance": provenance.to_dict() if provenance is not None else None,
        "mapper": take(mapper.state_dict(), mapper.field, mapper.optimizer, storage),
        "extra": copy.deepcopy(dict(extra or {})),
    }


def write_checkpoint(path: str | Path, taken: dict) -> None:
    """Pack the tables of a `take_checkpoint` copy and write it to `path` atomically."""
    path = Path(path)
    payload = {**taken, "mapper": compress(taken["mapper"])}
    tmp = path.with_name(path.name + ".tmp")
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(tmp, "wb") as f:
        torch.save(payload, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


REQUIRED_KEYS = ("version", "frame_index", "signature", "model_config", "mapper", "extra")


def read_checkpoint(path: str | Path) -> dict:
    """The checkpoint's payload, checked for form; DataError (one line) when it is not one."""
    path = Path(path)
    if path.is_dir():
        raise DataError(
            f"checkpoint {path} is a directory; point mapping.resume at its checkpoint.pt"
        )
    if not path.is_file():
        raise DataError(f"checkpoint {path} does not exist; check mapping.resume")
    try:
        # RNG states must stay on the CPU; load_state_dict moves tensors to the mapper's device.
        # A foreign file makes torch warn about its pickle protocol: the one line below says it.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # truncated or foreign file: say which file, not a pickle trace
        raise DataError(
            f"checkpoint {path} is unreadable ({type(exc).__name__}); point mapping.resume at a good checkpoint.pt"
        ) from exc
    if not isinstance(payload, dict) or payload.get("version") not in READABLE_VERSIONS:
        raise DataError(
            f"checkpoint {path} is not a SemanticFeels mapper checkpoint (version {FORMAT_VERSION})"
        )
    missing = [k for k in REQUIRED_KEYS if k not in payload]
    if missing:
        raise DataError(
            f"checkpoint {path} lacks {', '.join(missing)}; it is damaged, point mapping.resume at a good checkpoint.pt"
        )
    return payload


def read_provenance(path: str | Path) -> Provenance:
    """The provenance recorded in `path`; ConfigError for a checkpoint that predates it."""
    payload = read_checkpoint(path)
    recorded = payload.get("provenance")
    if not recorded:
        raise ConfigError(
            f"checkpoint {path} records no object, sensor or classes (format {payload['version']}); "
            "it cannot be resumed safely, start a new run"
        )
    try:
        return Provenance.from_dict(recorded)
    except (KeyError, TypeError, ValueError) as exc:
        raise DataError(
            f"checkpoint {path} has a damaged provenance record ({exc}); start a new run"
        ) from exc


def load_checkpoint(
    path: str | Path, mapper: OnlineMapper, model_config: dict | None = None
) -> dict:
    """Restore `mapper` from `path`; returns {"frame_index": int, "extra": dict}.

    Raises ConfigError when the checkpoint was written for a different model (field class,
    class count, parameter shapes, or `model_config` when both sides give one).
    """
    payload = read_checkpoint(path)
    saved, current = payload["signature"], field_signature(mapper)
    if saved != current:
        diff = [k for k in current if saved.get(k) != current[k]]
        raise ConfigError(
            f"checkpoint {path} was written for a different model ({', '.join(diff)} differ); resume with the model config it was trained with"
        )
    saved_config = payload["model_config"]
    if model_config is not None and saved_config is not None:
        keys = differing_settings(saved_config, model_config)
        if keys:
            raise ConfigError(
                f"checkpoint {path} was written with a different model config ({', '.join(keys)}); resume with the same model settings"
            )
    mapper.load_state_dict(decode(payload["mapper"], mapper.field, f"checkpoint {path}"))
    if (init_rng := payload["mapper"].get(INIT_KEY)) is not None:
        adopt_init_state(mapper.field, init_rng)  # its untouched rows are the saved run's
    return {"frame_index": int(payload["frame_index"]), "extra": payload["extra"]}
