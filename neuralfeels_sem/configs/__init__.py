"""Structured-config schemas, one module per config group.

Each module defines (or, for the model and mapping groups, imports from beside the class
they configure, e.g. MapperConfig from mapping/mapper.py) dataclasses whose field defaults
are the only defaults and whose `__post_init__` checks ranges, and a `register(cs)`
function that stores them under `schema/<group>/<name>`. A yaml file
in conf/<group>/ extends its schema with `- /schema/<group>/<name>@_here_` in its
defaults list. Types are checked by OmegaConf while composing; ranges are checked
by `validate_config` (run.py calls it before the task).
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path
from typing import Any, TypeVar

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from neuralfeels_sem.core.errors import ConfigError

_registered = False
T = TypeVar("T")


def to_config(schema: type[T], node: Any) -> T:
    """A config node (DictConfig, plain dict, or already an instance) as a `schema` instance.

    Interpolations are resolved against the node's root first; building the dataclass runs
    its range checks. Keys the node leaves out take the dataclass defaults.
    """
    if isinstance(node, schema):
        return node
    data = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node
    return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(schema), data))


_config_subdirs: dict[str, str] = {}


def config_subdir(output_dir: str, stamp: str) -> str:
    """hydra.output_subdir: `.hydra`, or `.hydra/resumed_<stamp>` for a run continuing in a
    directory whose `.hydra/` holds its first segment's config (kept as it was).

    Decided once per directory and process: after Hydra writes the config, the same
    question would get the other answer.
    """
    if output_dir not in _config_subdirs:
        continuing = (Path(output_dir) / ".hydra" / "config.yaml").is_file()
        _config_subdirs[output_dir] = f".hydra/resumed_{stamp}" if continuing else ".hydra"
    return _config_subdirs[output_dir]


def register_configs() -> None:
    """Import every schema module in this package and register it (idempotent)."""
    global _registered
    if _registered:
        return
    # ${len:${materials}} gives the number of classes to model and classifier configs.
    if not OmegaConf.has_resolver("len"):
        OmegaConf.register_new_resolver("len", lambda value: len(value))
    # hydra.run.dir: a resumed map run continues in its checkpoint's directory.
    if not OmegaConf.has_resolver("resume_run_dir"):
        OmegaConf.register_new_resolver(
            "resume_run_dir",
            lambda resume, default: str(Path(resume).parent) if resume else default,
        )
    # ${at_pace:pace,offline_value,realtime_value}: a setting that depends on sensor.pace.
    # No default uses it now; the configs of runs recorded while one did still name it.
    if not OmegaConf.has_resolver("at_pace"):
        OmegaConf.register_new_resolver(
            "at_pace", lambda pace, offline, realtime: offline if pace == "offline" else realtime
        )
    if not OmegaConf.has_resolver("config_subdir"):
        OmegaConf.register_new_resolver("config_subdir", config_subdir)
    cs = ConfigStore.instance()
    for info in pkgutil.iter_modules(__path__):
        module = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(module, "register"):
            module.register(cs)
    _registered = True


def validate_config(cfg: DictConfig) -> None:
    """Run every schema's range checks; raise ConfigError with one line on failure."""
    try:
        # Top-level keys first: groups copy them by interpolation (e.g. eval.seed: ${seed}),
        # and the error should name the key the user set.
        from neuralfeels_sem.configs.root import RootConfig

        RootConfig(
            seed=cfg.get("seed", 0),
            materials=list(cfg.get("materials", [])),
            device=cfg.get("device", "auto"),
        )
        OmegaConf.to_object(cfg)
    except (ValueError, OmegaConfBaseException) as exc:
        msg = str(exc).strip().splitlines()[0]
        raise ConfigError(f"invalid config: {msg}") from exc
    # A `+key=value` addition is composed into a typed node without complaint.
    from neuralfeels_sem.configs.known_keys import check_known_keys

    check_known_keys(cfg)
