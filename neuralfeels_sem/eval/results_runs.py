"""Runs and sources of the results page: what each run directory holds and which oracles it used."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import yaml

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.eval.aggregate import read_job
from neuralfeels_sem.eval.oracles import ORACLES, oracles_used
from neuralfeels_sem.eval.results_code import code_drift
from neuralfeels_sem.eval.results_drift import (
    current_overrides,
    drift,
    redundant,
    show,
    unread_beside,
)
from neuralfeels_sem.eval.results_weights import weights_drift
from neuralfeels_sem.utils.nested import flatten

# Overrides that do not change what a run measures.
# `perception` (a preset of oracles) is not a setting here: the object tables have an
# oracles column and pool runs only with the same oracles, so realistic and oracle runs
# sit side by side there. `viz.plots` only decides whether pictures are drawn.
BOOKKEEPING_KEYS = ("seed", "experiment", "launcher", "perception", "viz.plots")
BOOKKEEPING_VALUES = {"task": "map", "sensor": "sim"}
GENERATED_NAME = re.compile(r"random_\d+")  # the name a generated object's metrics give it
SINGLE_MATERIAL_FLOOR = 100.0 - 1e-6  # majority map's mean-class % on a one-material object
OBJECT_LAYOUT = "config.object_layout"  # a custom mesh's drawn layout (metrics.json)
SUGGESTIONS = "touch_suggestions.json"  # an active run's plan (pipeline/touch_advisor.py)


@dataclass
class Run:
    path: Path
    overrides: dict[str, str]
    metrics: dict
    config: dict | None  # .hydra/config.yaml, unresolved
    # Today's config for this run's object, preset and groups, flattened and unresolved
    # (set by tasks/results_page.py); None: settings are read from the overrides alone.
    today: dict | None = None
    # Read from the run directory once, so the page needs nothing else from it
    # (eval/results_archive.py keeps them when the directory is gone): when metrics.json was
    # written (POSIX seconds), the final checkpoint's size, the active policy's touch plan.
    finished_at: float | None = None
    checkpoint_bytes: int | None = None
    touch_plan: dict | None = None

    @property
    def object(self) -> str:
        name = self.overrides.get("object") or get(self.metrics, "config.object")
        if name is None and self.config:
            name = get(self.config, "object.name")
        if (
            name is not None
            and GENERATED_NAME.fullmatch(str(name))
            and "object.seed" in self.overrides
        ):
            # a generated object picked by a preset (experiment=unseen_objects): its metrics
            # name it by its seed, which the setting already carries; `object=random` as
            # an override names it "random"
            return "random"
        return str(name) if name is not None else "unknown"

    @property
    def seed(self) -> int | None:
        seed = self.overrides.get("seed", get(self.metrics, "config.seed"))
        if seed is None and self.config:
            seed = self.config.get("seed")
        try:
            return int(seed)
        except (TypeError, ValueError):
            return None

    @cached_property  # runs are not changed once loaded: dataclasses.replace makes a new one
    def setting(self) -> dict[str, str]:
        """What the run measures beside today's default config (not the object or the seed):
        its overrides, less those that set today's default, plus the defaults it ran with
        that have changed since (`drift`)."""
        explicit = {
            k: v
            for k, v in self.overrides.items()
            if k != "object"
            and k not in BOOKKEEPING_KEYS
            and not k.startswith("hydra")
            and BOOKKEEPING_VALUES.get(k) != v
        }
        if self.today is None:
            return explicit
        same = redundant(explicit, self.today)
        out = {k: v for k, v in explicit.items() if k not in same}
        return out | {k: show(old) for k, (old, _) in self.drift.items()}

    @cached_property
    def drift(self) -> dict[str, tuple]:
        """{key: (value the run used, today's default)} for defaults changed since the run,
        the shipped networks' weights (results_weights.py) and behaviour changed without a
        key (results_code.py) among them."""
        if self.today is None or self.config is None:
            return {}
        commit = get(self.metrics, "code.commit")
        flat = flatten(self.config)
        weights = weights_drift(flat, self.overrides, commit)
        return drift(self.config, self.overrides, self.today) | weights | code_drift(flat, commit)

    @property
    def single_material(self) -> bool:
        floor = get(self.metrics, "baseline_majority.matching_mean_class_pct")
        if floor is not None:
            return floor >= SINGLE_MATERIAL_FLOOR
        per_class = self.metrics.get("matching_per_class")
        return isinstance(per_class, dict) and len(per_class) == 1


@dataclass
class Source:
    path: Path
    kind: str  # "run" or "sweep"
    runs: list[Run]
    failed: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        return display_path(self.path)


# ---------------------------------------------------------------------------- reading
def get(data: Any, dotted: str) -> Any:
    """data['a']['b'] for 'a.b'; None where any level is missing."""
    for key in dotted.split("."):
        if not isinstance(data, dict) or key not in data:
            return None
        data = data[key]
    return data


def display_path(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _load_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DataError(f"{path} is unreadable: {exc}") from None
    if not isinstance(data, dict):
        raise DataError(f"{path} does not hold a JSON object")
    return data


def _load_yaml(path: Path) -> Any:
    if not path.is_file():
        return None
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return None


def _overrides(run_dir: Path) -> dict[str, str]:
    raw = _load_yaml(run_dir / ".hydra" / "overrides.yaml") or []
    items = [str(o) for o in raw if "=" in str(o)] if isinstance(raw, list) else []
    return current_overrides(dict(o.lstrip("+~").split("=", 1) for o in items))


def _run(run_dir: Path, metrics: dict | None = None) -> Run:
    config = _load_yaml(run_dir / ".hydra" / "config.yaml")
    return Run(
        path=run_dir,
        overrides=_overrides(run_dir),
        metrics=_load_json(run_dir / "metrics.json") if metrics is None else metrics,
        config=config if isinstance(config, dict) else None,
        finished_at=_stat(run_dir / "metrics.json", "st_mtime"),
        checkpoint_bytes=_stat(run_dir / "checkpoint.pt", "st_size"),
        touch_plan=_touch_plan(run_dir / SUGGESTIONS),
    )


def _stat(path: Path, field_name: str):
    try:
        return getattr(path.stat(), field_name)
    except OSError:
        return None


def _touch_plan(path: Path) -> dict | None:
    """`touch_plan` of an active run's touch_suggestions.json (None: none or unreadable)."""
    try:
        plan = json.loads(path.read_text()).get("touch_plan")
    except (OSError, ValueError, AttributeError):
        return None
    return plan if isinstance(plan, dict) else None


def _job_order(path: Path) -> tuple:
    return (0, int(path.name), "") if path.name.isdigit() else (1, 0, path.name)


def load_source(path: Path) -> Source:
    """A run or sweep directory; a DataError naming the path for anything else."""
    if not path.is_dir():
        raise DataError(f"{path}: no such directory")
    if (path / "metrics.json").is_file():
        return Source(path, "run", [_run(path)])
    source = Source(path, "sweep", [])
    for job_dir in sorted((d for d in path.iterdir() if d.is_dir()), key=_job_order):
        job = read_job(job_dir)
        if job is None:
            continue
        if job["status"] == "failed":
            source.failed.append(job_dir.name)
        elif (job_dir / "metrics.json").is_file():
            try:
                source.runs.append(_run(job_dir))
            except DataError:
                source.failed.append(job_dir.name)
        else:
            source.missing.append(job_dir.name)
    if not source.runs and not source.failed:
        raise DataError(
            f"{path}: neither a run directory (no metrics.json) nor a sweep directory "
            "(no job sub-directory with metrics.json and .hydra/overrides.yaml)"
        )
    return source


# ---------------------------------------------------------------------------- oracles
def oracles_of(run: Run) -> tuple[tuple[str, ...] | None, str]:
    """(oracle names, where they were read) or (None, reason) when nothing tells."""
    recorded = run.metrics.get("oracles")
    if isinstance(recorded, list):
        return tuple(str(o) for o in recorded), "metrics.json"
    if run.config is not None:
        return tuple(oracles_used(run.config)), ".hydra/config.yaml"
    return None, "not recorded"


def describe_oracles(names: Sequence[str]) -> str:
    if not names:
        return "none (every input perceived as on a real rig)"
    return "; ".join(ORACLES.get(n, n) for n in names)


def reference_run(
    run: Run, candidates: Sequence[Run], dropped: Sequence[str] = (), varied: str = ""
) -> Run | None:
    """The run of the same object, seed and settings that `run` is compared with, but for
    the setting `varied` (the pose source, the touch policy) left at today's default.

    Its oracles must be those of `run` plus, at most, the ones named in `dropped` (a
    tracked run drops `object_pose`, which its `pose=gt` reference uses); None when no
    such run is among the candidates. Settings the reference never reads at its value of
    `varied` (results_drift.UNREAD_IN: a `pose=gt` run, the tracker's) are left out.
    """
    names, _ = oracles_of(run)
    own = set(names or ()) - set(dropped)
    unread = unread_beside(varied)
    rest = {k: v for k, v in run.setting.items() if k != varied and not k.startswith(unread)}
    for other in candidates:
        if other.setting != rest or other.object != run.object or other.seed != run.seed:
            continue
        theirs, _ = oracles_of(other)
        if theirs is not None and set(theirs) - set(dropped) == own:
            return other
    return None
