"""A field whose initial parameters can be drawn again: what lets a checkpoint skip them.

Most rows of the hash table are never updated in a short run (no training point fell in
their cells) and still hold their random initial values. `build_field` records the CPU
random state the field was constructed from; `initial_state` constructs the same field
again from that state (without disturbing the global random stream) and returns its
state_dict, so a checkpoint stores the updated rows only and rebuilds the others on load
(mapping/checkpoint_codec.py). A field not built here has no recorded state and its
checkpoints store every row.

The record is kept beside the field (a weak mapping: it goes when the field goes), not in
the field, because it describes how the field was made, not what it has learned.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor, nn

from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig


@dataclass(frozen=True)
class _Recipe:
    construct: Callable[[], nn.Module]  # builds the field afresh (same config, same bound)
    rng_state: Tensor  # torch's CPU random state just before the field was constructed


_RECIPES: weakref.WeakKeyDictionary[nn.Module, _Recipe] = weakref.WeakKeyDictionary()
# Initial values of a field's large tables, drawn once and kept on the field's device: every
# checkpoint compares the never-updated rows with them (mapping/checkpoint_codec.py), and
# drawing 133 million rows again per checkpoint cost seconds of the training thread.
_INITIAL_TABLES: weakref.WeakKeyDictionary[nn.Module, dict[str, Tensor]] = (
    weakref.WeakKeyDictionary()
)


def build_field(config: SemanticFieldConfig, bound: float) -> SemanticField:
    """SemanticField(config, bound), with its construction recorded for `initial_state`."""
    rng_state = torch.get_rng_state()
    field = SemanticField(config, bound)
    _RECIPES[field] = _Recipe(lambda: SemanticField(config, bound), rng_state)
    return field


def init_rng_state(field: nn.Module) -> Tensor | None:
    """The CPU random state `field` was constructed from; None when it was not recorded."""
    recipe = _RECIPES.get(field)
    return None if recipe is None else recipe.rng_state


def initial_state(field: nn.Module, rng_state: Tensor | None = None) -> dict[str, Tensor] | None:
    """The state_dict `field` had when constructed from `rng_state` (default: its own
    recorded state), on the CPU; None when `field` was not built by `build_field`."""
    recipe = _RECIPES.get(field)
    if recipe is None:
        return None
    with torch.random.fork_rng(devices=[]):  # the caller's random stream is left as it was
        torch.set_rng_state(recipe.rng_state if rng_state is None else rng_state)
        return recipe.construct().state_dict()


def initial_tables(field: nn.Module, names: list[str]) -> dict[str, Tensor] | None:
    """The initial values of `field`'s state_dict entries `names`, each on its entry's
    device; drawn on the first call for `field` and kept while it lives (call it first on
    the thread that owns torch's random stream: the draw forks it). None when `field` was
    not built by `build_field`."""
    if field not in _RECIPES:
        return None
    kept = _INITIAL_TABLES.get(field)
    if kept is None or any(name not in kept for name in names):
        drawn, live = initial_state(field), field.state_dict()
        kept = {name: drawn[name].to(live[name].device) for name in names}
        _INITIAL_TABLES[field] = kept
    return {name: kept[name] for name in names}


def adopt_init_state(field: nn.Module, rng_state: Tensor) -> None:
    """After loading a checkpoint: `field` now holds rows initialised from `rng_state` (the
    run that wrote it), so later checkpoints rebuild them from that state."""
    recipe = _RECIPES.get(field)
    if recipe is not None:
        _RECIPES[field] = _Recipe(recipe.construct, rng_state.clone())
        _INITIAL_TABLES.pop(field, None)
