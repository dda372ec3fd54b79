"""Structured-config schemas, one module per config group.

Each module defines dataclasses whose `__post_init__` checks ranges, and a
`register(cs)` function that stores them under `schema/<group>/<name>`. A yaml file
in conf/<group>/ extends its schema with `- /schema/<group>/<name>@_here_` in its
defaults list. Types are checked by OmegaConf while composing; ranges are checked
by `validate_config` (run.py calls it before the task).
"""

from __future__ import annotations

import importlib
import pkgutil

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from neuralfeels_sem.errors import ConfigError

_registered = False


def register_configs() -> None:
    """Import every schema module in this package and register it (idempotent)."""
    global _registered
    if _registered:
        return
    # ${len:${materials}} gives the number of classes to model and classifier configs.
    if not OmegaConf.has_resolver("len"):
        OmegaConf.register_new_resolver("len", lambda value: len(value))
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
