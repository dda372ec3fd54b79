"""Refuse config keys that no code reads.

Every group node is typed by its schema dataclass, so Hydra refuses `mapping.foo=1`; but
a `+mapping.foo=1` addition (which Hydra's own error message suggests) slips into a typed
node and would be silently ignored. After composition every key of a typed node must be
one of its dataclass's fields.
"""

from __future__ import annotations

import dataclasses
import difflib

from omegaconf import DictConfig, ListConfig, OmegaConf

from neuralfeels_sem.core.errors import ConfigError

# Hydra's instantiate reads these on any node.
_INSTANTIATE_KEYS = {"_target_", "_partial_", "_convert_", "_recursive_", "_args_"}


def unknown_keys(node: DictConfig | ListConfig, path: str = "") -> list[tuple[str, set[str]]]:
    """(dotted key, the known keys beside it) for every key its schema does not have."""
    found: list[tuple[str, set[str]]] = []
    if isinstance(node, ListConfig):
        for i in range(len(node)):
            child = node._get_node(i)
            if isinstance(child, (DictConfig, ListConfig)) and not child._is_missing():
                found += unknown_keys(child, f"{path}[{i}]")
        return found
    schema = OmegaConf.get_type(node)
    known = (
        {f.name for f in dataclasses.fields(schema)} | _INSTANTIATE_KEYS
        if dataclasses.is_dataclass(schema)
        else None
    )
    for key in node:
        dotted = f"{path}.{key}" if path else str(key)
        if known is not None and key not in known:
            found.append((dotted, known))
        child = node._get_node(key)
        if isinstance(child, (DictConfig, ListConfig)) and not child._is_missing():
            found += unknown_keys(child, dotted)
    return found


def check_known_keys(cfg: DictConfig) -> None:
    """ConfigError in one line naming the first unknown key and the closest known one."""
    for dotted, known in unknown_keys(cfg):
        if dotted == "hydra":
            continue
        name = dotted.rsplit(".", 1)[-1]
        parent = dotted[: -len(name) - 1] if "." in dotted else ""
        close = difflib.get_close_matches(name, sorted(known - _INSTANTIATE_KEYS), n=1)
        hint = (
            f"did you mean {parent + '.' if parent else ''}{close[0]}?"
            if close
            else "docs/configuration.md lists the settings"
        )
        raise ConfigError(f"unknown key {dotted}: no code reads it; {hint}")
