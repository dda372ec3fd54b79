"""Which of a run's settings differ from today's defaults.

A run keeps the config it ran with (`.hydra/config.yaml`, unresolved). When a default
changes after the run (the simulated run's length, a mapper setting), a run without
overrides no longer measures today's default config, and an override that set today's
value is no longer another setting. The results page compares each run's recorded config,
key by key, with today's config composed from the same object, experiment, perception
preset and config groups (`tasks/results_page.py` composes it), and reads the run's
setting from the differences.
"""

from __future__ import annotations

from typing import Any

import yaml
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from neuralfeels_sem.utils.nested import flatten

# Keys never compared: the object group is what the run is about (a generated object's
# seed, a custom mesh), hydra's own settings are bookkeeping, and these keys only name
# the run, decide whether pictures are drawn, when the state is saved (a checkpoint
# changes nothing the run maps: a resumed run continues bit for bit) or at which priority
# helper threads run (read offline only, where every frame is mapped in order).
IGNORED_PREFIXES = ("object.", "hydra.")
IGNORED_KEYS = frozenset({"seed", "viz.plots", "mapping.checkpoint_every", "mapping.helper_nice"})
_MISSING = object()

# Config-group options removed since, with the option that composes the same config today
# (None: the group's default). model=semantic_sdf_material_grid was semantic_sdf with
# model.material.grid_levels=4, which became semantic_sdf's own default.
RETIRED_OPTIONS: dict[tuple[str, str], str | None] = {
    ("model", "semantic_sdf_material_grid"): None,
}


def current_overrides(overrides: dict[str, str]) -> dict[str, str]:
    """A run's overrides with retired group options replaced by today's equivalent."""
    out = {}
    for key, value in overrides.items():
        now = RETIRED_OPTIONS.get((key, value), value)
        if now is not None:
            out[key] = now
    return out


def same_value(a: Any, b: Any) -> bool:
    """Equal as config values: 20 and 20.0 are the same, True and 1 are not."""
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return float(a) == float(b)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def parse_override(value: str) -> Any:
    """An override's value as Hydra reads it (YAML scalars and lists; else the string)."""
    try:
        return yaml.safe_load(value)
    except yaml.YAMLError:
        return value


def show(value: Any) -> str:
    """A config value as an override writes it."""
    if isinstance(value, list | tuple):
        return "[" + ",".join(show(v) for v in value) + "]"
    if value is None:
        return "null"
    return str(value).lower() if isinstance(value, bool) else str(value)


# Settings read only in some modes, or that change nothing a run maps in them: {prefix:
# (the key that picks the mode, its value in which they are unread)}. A run that read the
# simulator's pose never ran the tracker; a scripted gait never asks the touch planner nor
# waits for advice; an active run turned as the gait turns compares no turns; at offline
# pace the acquisition thread and the simulator's own process change the loop's wall time,
# not one figure of the map (tests/pipeline/test_pipeline.py).
UNREAD_IN: dict[str, tuple[str, str]] = {
    "mapping.tracker.": ("mapping.pose", "gt"),
    "sensor.planner.": ("sensor.policy", "scripted"),
    "sensor.advice_lag_frames": ("sensor.policy", "scripted"),
    "sensor.planner.turn_": ("sensor.planner.turn", "gait"),
    "mapping.acquire_thread": ("sensor.pace", "offline"),
    "mapping.acquire_process": ("sensor.pace", "offline"),
}


def unread_beside(mode_key: str) -> tuple[str, ...]:
    """Prefixes of the settings that UNREAD_IN ties to `mode_key`: a run compared with its
    reference at that mode's unread value (a tracked run with its `pose=gt` run) differs
    from it in them without being another setting."""
    return tuple(prefix for prefix, (key, _) in UNREAD_IN.items() if key == mode_key)


def compared(key: str, flat: dict[str, Any] | None = None) -> bool:
    """Whether a recorded leaf can make the run another setting (`flat`: the run's other
    leaves, for settings its mode never read)."""
    if key in IGNORED_KEYS or key.startswith(IGNORED_PREFIXES):
        return False
    for prefix, (mode_key, unread) in UNREAD_IN.items():
        if key.startswith(prefix) and flat is not None and str(flat.get(mode_key)) == unread:
            return False
    return True


# Settings added since with a default that changes what a run does: {key: (a key every run
# recorded when it was added, the value runs that recorded that key but not this one ran
# with)}. classifier.patch_probe came with 0 (every patch read); the default became 2.
# mapping.tracker.max_points_per_finger came with 1000 (the camera's cap, which applied to
# every source before); the default became 200. mapping.mapper.label_vote_steady_frames
# came with 0 (no press backs itself); the default became 3. sensor.planner.weigh_by_contact
# came with true: the active runs before it ranked by score alone. The networks' cpu_runtime
# came with onnxruntime: runs before it ran them in torch. classifier.edge_min_confidence
# came with null (off); the default became 0.99. classifier.edge_long_streak_frames came
# with 0 (off). classifier.edge_extent came with whole (the label covers the imprint).
# mapping.mapper.fill_m came with 0.01: runs before it read the material branch alone.
# sensor.tactile.ignored_faces came with nearest: runs before it pressed ignored faces as a
# texture of no material. sensor.planner.turn came with gait (the default became advance),
# and turn_offered_weight with 1.0 (the default became 0.3).
ADDED_SINCE: dict[str, tuple[str, Any]] = {
    "classifier.patch_probe": ("classifier.max_patches", 0),
    "mapping.tracker.max_points_per_finger": ("mapping.tracker.max_points_per_source", 1000),
    "mapping.mapper.label_vote_steady_frames": ("mapping.mapper.label_vote_press_gap", 0),
    "sensor.planner.weigh_by_contact": ("sensor.planner.candidates", False),
    "sensor.planner.turn": ("sensor.planner.candidates", "gait"),
    "sensor.planner.turn_offered_weight": ("sensor.planner.turn", 1.0),
    "classifier.cpu_runtime": ("classifier.cuda_graphs", "torch"),
    "classifier.edge_min_confidence": ("classifier.min_confidence", None),
    "classifier.edge_long_streak_frames": ("classifier.edge_streak_frames", 0),
    "classifier.edge_extent": ("classifier.max_edge_share", "whole"),
    "mapping.mapper.fill_m": ("mapping.mapper.material_weight", None),
    "mapping.mapper.tactile_depth.cpu_runtime": (
        "mapping.mapper.tactile_depth.min_contact_px",
        "torch",
    ),
    "sensor.tactile.ignored_faces": ("sensor.tactile.texture_scale", "generic"),
    "mapping.mapper.space_prior_margin": ("mapping.mapper.space_prior_weight", 0.0),
}


def drift(recorded: dict, overrides: dict[str, str], today: dict[str, Any]) -> dict[str, tuple]:
    """{key: (the run's value, today's default)} for every compared leaf the run did not
    override whose recorded value differs from today's; keys only one side has are skipped
    (a setting added or removed since), except those of ADDED_SINCE."""
    out = {}
    flat = flatten(recorded)
    for key, (sibling, value) in ADDED_SINCE.items():
        if sibling in flat:
            flat.setdefault(key, value)
    for key, value in flat.items():
        now = today.get(key, _MISSING)
        if key in overrides or now is _MISSING or not compared(key, flat):
            continue
        if _interpolated(value) and not _interpolated(now):
            value = resolved(recorded, key, value)
        if not same_value(value, now):
            out[key] = (value, now)
    return out


def _interpolated(value: Any) -> bool:
    return isinstance(value, str) and "${" in value


def resolved(recorded: dict, key: str, value: str) -> Any:
    """A recorded interpolation's value in the run's own config (label_vote_press_reach
    followed sensor.pace once, `${at_pace:...}`, where today's default is a plain value);
    the text as recorded when it does not resolve to a plain value (a resolver no longer
    registered, a key the run's config lacks)."""
    try:
        out = OmegaConf.select(OmegaConf.create(recorded), key, throw_on_resolution_failure=True)
    except (OmegaConfBaseException, ValueError):
        return value
    return out if out is None or isinstance(out, str | int | float | bool) else value


def redundant(overrides: dict[str, str], today: dict[str, Any]) -> set[str]:
    """Overridden leaves whose value is today's default (no longer another setting)."""
    return {
        key
        for key, value in overrides.items()
        if key in today and same_value(parse_override(value), today[key])
    }


def group_overrides(overrides: dict[str, str], recorded: dict | None) -> list[str]:
    """The overrides that pick config groups or presets (not leaves of the recorded config):
    today's config must be composed with them for the leaves to be comparable."""
    leaves = flatten(recorded) if recorded else {}
    return [
        f"{key}={value}"
        for key, value in sorted(overrides.items())
        # launcher picks only hydra's own launcher config: nothing to compare, and composing
        # it would need the launcher's plugin
        if key not in leaves and not key.startswith("hydra") and key != "launcher"
    ]
