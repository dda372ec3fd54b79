"""Write the results page (docs/results.md) from run outputs.

    python -m neuralfeels_sem.eval.results_page --out docs/results.md DIR [DIR ...]

Each DIR is a run directory (holds `metrics.json`) or a sweep directory (job
sub-directories with `metrics.json` and `.hydra/overrides.yaml`, as `-m` writes them).
The page has four parts:
- multi-material objects (default config): mean-class matching per seed and mean ± std,
  beside the majority-material map and the margin over it; matching and shape-aware
  matching, F-score, classifier accuracy on judged touches and coverage;
- single-material objects (the majority map already scores 100 %): classifier accuracy on
  judged touches, coverage, accuracy over all touches, F-score;
- every other setting (ablations, runs with overrides), one table per source;
- per source: the simulator oracles the runs used, the machine and load where recorded.
A run belongs to the first two parts when its only overrides are the object, the seed and
bookkeeping (experiment preset, launcher, hydra.*); any other override makes it a setting.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from neuralfeels_sem.core.errors import DataError, UserError
from neuralfeels_sem.eval.aggregate import read_job

COMMAND = "python -m neuralfeels_sem.eval.results_page"
# Overrides that do not change what a run measures.
BOOKKEEPING_KEYS = ("seed", "experiment", "launcher")
BOOKKEEPING_VALUES = {"task": "map", "sensor": "sim"}
# What each simulator oracle is (names as metrics.json["oracles"]); a real rig has none.
ORACLES = {
    "object_pose": "ground-truth object pose (mapping.pose=gt)",
    "camera_mask": "the simulator's camera object mask (mapping.mapper.use_camera_mask=true)",
    "tactile_contact_depth": "the simulator's tactile contact depth (mapping.mapper.tactile_depth.source=gt)",
    "noise_free_depth": "noise-free camera depth (sensor.rgbd.depth_noise_std=0)",
    "material_labels": "ground-truth material labels (classifier=oracle)",
}
SINGLE_MATERIAL_FLOOR = 100.0 - 1e-6  # majority map's mean-class % on a one-material object


@dataclass
class Run:
    path: Path
    overrides: dict[str, str]
    metrics: dict
    config: dict | None  # .hydra/config.yaml, unresolved

    @property
    def object(self) -> str:
        name = self.overrides.get("object") or get(self.metrics, "config.object")
        if name is None and self.config:
            name = get(self.config, "object.name")
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

    @property
    def setting(self) -> dict[str, str]:
        """Overrides that change what the run measures (not the object or the seed)."""
        return {
            k: v
            for k, v in self.overrides.items()
            if k != "object"
            and k not in BOOKKEEPING_KEYS
            and not k.startswith("hydra")
            and BOOKKEEPING_VALUES.get(k) != v
        }

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
    return dict(o.lstrip("+~").split("=", 1) for o in items)


def _run(run_dir: Path, metrics: dict | None = None) -> Run:
    config = _load_yaml(run_dir / ".hydra" / "config.yaml")
    return Run(
        path=run_dir,
        overrides=_overrides(run_dir),
        metrics=_load_json(run_dir / "metrics.json") if metrics is None else metrics,
        config=config if isinstance(config, dict) else None,
    )


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
def oracles_from_config(config: dict) -> list[str]:
    """The oracles a run used, from its composed config (as tasks/build.py oracles_used records them)."""
    sensor = config.get("sensor") or {}
    if sensor.get("name") != "sim":
        return []
    mapping = config.get("mapping") or {}
    mapper = mapping.get("mapper") or {}
    depth_noise = (sensor.get("rgbd") or {}).get("depth_noise_std", 0.0)
    try:
        noise_free = float(depth_noise) == 0.0
    except (TypeError, ValueError):
        noise_free = False
    used = {
        "object_pose": mapping.get("pose") == "gt",
        "camera_mask": mapper.get("use_camera_mask") is True,
        "tactile_contact_depth": (mapper.get("tactile_depth") or {}).get("source") == "gt",
        "noise_free_depth": noise_free,
        "material_labels": str((config.get("classifier") or {}).get("_target_", "")).endswith(
            "OracleClassifier"
        ),
    }
    return [name for name, on in used.items() if on]


def oracles_of(run: Run) -> tuple[tuple[str, ...] | None, str]:
    """(oracle names, where they were read) or (None, reason) when nothing tells."""
    recorded = run.metrics.get("oracles")
    if isinstance(recorded, list):
        return tuple(str(o) for o in recorded), "metrics.json"
    if run.config is not None:
        return tuple(oracles_from_config(run.config)), ".hydra/config.yaml"
    return None, "not recorded"


def describe_oracles(names: Sequence[str]) -> str:
    if not names:
        return "none (every input perceived as on a real rig)"
    return "; ".join(ORACLES.get(n, n) for n in names)


# ---------------------------------------------------------------------------- statistics
def values_of(runs: Iterable[Run], key: str, scale: float = 1.0) -> list[float]:
    out = []
    for run in runs:
        value = get(run.metrics, key)
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if number and math.isfinite(float(value)):
            out.append(scale * float(value))
    return out


def mean(values: Sequence[float]) -> float | None:
    return sum(values) / len(values) if values else None


def std(values: Sequence[float]) -> float | None:
    """Sample standard deviation (n - 1); 0 for one value."""
    if not values:
        return None
    if len(values) == 1:
        return 0.0
    m = sum(values) / len(values)
    return math.sqrt(sum((v - m) ** 2 for v in values) / (len(values) - 1))


def fmt(value: float | None, digits: int = 1, sign: bool = False) -> str:
    if value is None:
        return "n/a"
    return f"{value:+.{digits}f}" if sign else f"{value:.{digits}f}"


def mean_std(values: Sequence[float], digits: int = 1) -> str:
    if not values:
        return "n/a"
    return f"{fmt(mean(values), digits)} ± {fmt(std(values), digits)}"


def margins(runs: Sequence[Run]) -> list[float]:
    """Mean-class matching minus the majority map's, per run."""
    out = []
    for run in runs:
        margin = get(run.metrics, "margin_over_majority.matching_mean_class_pct")
        if margin is None:
            value = get(run.metrics, "matching_mean_class_pct")
            floor = get(run.metrics, "baseline_majority.matching_mean_class_pct")
            margin = value - floor if value is not None and floor is not None else None
        if margin is not None:
            out.append(float(margin))
    return out


def seeds_text(runs: Sequence[Run]) -> str:
    seeds = sorted({s for r in runs if (s := r.seed) is not None})
    if not seeds:
        return "n/a"
    runs_of_seeds: list[list[int]] = [[seeds[0]]]
    for seed in seeds[1:]:
        if seed == runs_of_seeds[-1][-1] + 1:
            runs_of_seeds[-1].append(seed)
        else:
            runs_of_seeds.append([seed])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs_of_seeds)


def by_seed(runs: Sequence[Run]) -> list[Run]:
    return sorted(runs, key=lambda r: (r.seed is None, r.seed or 0, str(r.path)))


def majority_cells(runs: Sequence[Run]) -> tuple[str, str]:
    """(majority map's mean-class %, its matching %), the first with the material's name."""
    materials = sorted(
        {str(m) for r in runs if (m := get(r.metrics, "baseline_majority.material"))}
    )
    floor = fmt(mean(values_of(runs, "baseline_majority.matching_mean_class_pct")))
    if materials and floor != "n/a":
        floor += f" ({', '.join(materials)})"
    return floor, fmt(mean(values_of(runs, "baseline_majority.matching_pct")))


def matching_cell(runs: Sequence[Run]) -> str:
    """Plain matching, never alone: its mean with the majority map's in brackets."""
    _, floor = majority_cells(runs)
    return f"{fmt(mean(values_of(runs, 'matching_pct')))} ({floor})"


# ---------------------------------------------------------------------------- tables
def table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return lines


def group_by(runs: Iterable[Run], key) -> dict[Any, list[Run]]:
    groups: dict[Any, list[Run]] = {}
    for run in runs:
        groups.setdefault(key(run), []).append(run)
    return groups


def multi_material_table(runs: Sequence[Run]) -> list[str]:
    rows = []
    for obj, members in group_by(runs, lambda r: r.object).items():
        members = by_seed(members)
        per_seed = ", ".join(
            fmt(get(r.metrics, "matching_mean_class_pct"))
            for r in members
            if get(r.metrics, "matching_mean_class_pct") is not None
        )
        floor, _ = majority_cells(members)
        rows.append(
            [
                f"`{obj}`",
                seeds_text(members),
                per_seed or "n/a",
                "**" + mean_std(values_of(members, "matching_mean_class_pct")) + "**",
                floor,
                fmt(mean(margins(members)), sign=True),
                matching_cell(members),
                fmt(mean(values_of(members, "matching_mesh_pct"))),
                fmt(mean(values_of(members, "fscore_5mm")), 3),
                fmt(mean(values_of(members, "classifier_accuracy.overall", 100.0))),
                fmt(mean(values_of(members, "classifier_accuracy.coverage", 100.0))),
            ]
        )
    return table(
        [
            "object",
            "seeds",
            "mean-class % per seed",
            "mean-class % (mean ± std)",
            "majority map % (material)",
            "margin",
            "matching % (majority)",
            "on mesh %",
            "F-score @5 mm",
            "classifier acc. %",
            "coverage %",
        ],
        rows,
    )


def single_material_table(runs: Sequence[Run]) -> list[str]:
    rows = []
    for obj, members in group_by(runs, lambda r: r.object).items():
        rows.append(
            [
                f"`{obj}`",
                str(len(members)),
                seeds_text(members),
                mean_std(values_of(members, "classifier_accuracy.overall", 100.0)),
                mean_std(values_of(members, "classifier_accuracy.coverage", 100.0)),
                mean_std(values_of(members, "classifier_accuracy.accuracy_all_touches", 100.0)),
                mean_std(values_of(members, "fscore_5mm"), 3),
            ]
        )
    return table(
        [
            "object",
            "runs",
            "seeds",
            "classifier acc. on judged touches %",
            "coverage %",
            "acc. over all touches %",
            "F-score @5 mm",
        ],
        rows,
    )


def setting_label(run: Run, keys: Sequence[str]) -> str:
    parts = [f"object={run.object}"] + [f"{k}={run.setting[k]}" for k in keys if k in run.setting]
    return ", ".join(parts)


def settings_table(source: Source, runs: Sequence[Run]) -> list[str]:
    """One row per setting (object and the overrides that vary in this source)."""
    keys = sorted({k for r in runs for k in r.setting})
    varying = [k for k in keys if len({r.setting.get(k) for r in runs}) > 1]
    constant = [k for k in keys if k not in varying]
    with_pose = any(get(r.metrics, "pose_error_mm") is not None for r in runs)
    rows = []
    for label, members in group_by(runs, lambda r: setting_label(r, varying)).items():
        floor, _ = majority_cells(members)
        row = [
            label,
            str(len(members)),
            "**" + mean_std(values_of(members, "matching_mean_class_pct")) + "**",
            floor,
            fmt(mean(margins(members)), sign=True),
            matching_cell(members),
            fmt(mean(values_of(members, "fscore_5mm")), 3),
        ]
        if with_pose:
            row.append(fmt(mean(values_of(members, "pose_error_mm")), 2))
        rows.append(row)
    header = [
        "setting",
        "runs",
        "mean-class % (mean ± std)",
        "majority map % (material)",
        "margin",
        "matching % (majority)",
        "F-score @5 mm",
    ] + (["pose error mm"] if with_pose else [])
    lines = [f"### `{source.label}`", ""]
    if constant:
        fixed = ", ".join(f"`{k}={runs[0].setting[k]}`" for k in constant)
        lines += [f"Every run here: {fixed}.", ""]
    return lines + table(header, rows)


# ---------------------------------------------------------------------------- sources
def machine_text(runs: Sequence[Run]) -> str:
    """The machines the runs used (each once) and the range of their 1-minute load averages."""
    machines, loads = [], []
    for run in runs:
        machine, load = run.metrics.get("machine"), run.metrics.get("load_avg")
        if isinstance(machine, dict):
            machine = ", ".join(f"{k} {v}" for k, v in machine.items())
        if machine and str(machine) not in machines:
            machines.append(str(machine))
        if isinstance(load, list | tuple) and load:
            load = load[0]
        if isinstance(load, int | float):
            loads.append(float(load))
    parts = [" | ".join(machines)] if machines else []
    if loads:
        low, high = min(loads), max(loads)
        span = f"{low:.1f}" if low == high else f"{low:.1f}-{high:.1f}"
        parts.append(f"1-minute load average at the end of the runs {span}")
    return "; ".join(parts) if parts else "not recorded"


def plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def source_lines(source: Source) -> list[str]:
    """A bullet per source: what it holds, then its oracles and machine as sub-bullets."""
    if source.kind == "run":
        what = "run directory"
    else:
        what = f"sweep: {plural(len(source.runs), 'run')} with metrics.json"
        if source.failed:
            what += f"; {len(source.failed)} failed: " + ", ".join(source.failed)
        if source.missing:
            what += f"; {len(source.missing)} without results: " + ", ".join(source.missing)
    found: dict[tuple[str, ...] | None, list[str]] = {}
    for run in source.runs:
        names, origin = oracles_of(run)
        found.setdefault(names, []).append(origin)
    lines = [f"- `{source.label}` ({what})"]
    for names, origins in found.items():
        who = "" if len(found) == 1 else f"{plural(len(origins), 'run')}, "
        if names is None:
            lines.append(
                f"  - oracles ({who}not recorded): no `oracles` in metrics.json "
                "and no .hydra/config.yaml"
            )
        else:
            where = ", ".join(sorted(set(origins)))
            lines.append(f"  - oracles ({who}from {where}): {describe_oracles(names)}")
    wall = values_of(source.runs, "wall_s")
    machine = f"  - machine/load: {machine_text(source.runs)}"
    if wall:
        low, high = f"{min(wall):.0f}", f"{max(wall):.0f}"
        machine += f"; wall time per run {low if low == high else f'{low}-{high}'} s"
    return lines + [machine]


# ---------------------------------------------------------------------------- page
def render(sources: Sequence[Source], command: str) -> str:
    runs = [r for s in sources for r in s.runs]
    default = [r for r in runs if not r.setting]
    multi = [r for r in default if not r.single_material]
    single = [r for r in default if r.single_material]
    lines = [
        "# Results",
        "",
        "<!-- Generated file: do not edit by hand. -->",
        "This page is generated from run outputs by",
        "",
        "```bash",
        command,
        "```",
        "",
        "The headline figure is mean-class matching (the mean over the materials present of",
        "each material's recall), always beside the majority map (a constant map painting the",
        "whole object in its majority material) and the margin between them. Plain matching is",
        "shown with the majority map's figure in brackets. Classifier figures are means over",
        "runs; every metric is defined in [evaluation](evaluation.md).",
        "",
        "## Multi-material objects",
        "",
    ]
    lines += multi_material_table(multi) if multi else ["No default-config multi-material runs."]
    lines += [
        "",
        "## Single-material objects",
        "",
        "The majority map scores 100 % here, so these objects are reported by the classifier:",
        "accuracy on judged touches, coverage (share of touches that got a label) and accuracy",
        "over all touches (an abstention counts as not correct).",
        "",
    ]
    lines += single_material_table(single) if single else ["No single-material runs."]
    lines += ["", "## Other settings", ""]
    other = False
    for source in sources:
        members = [r for r in source.runs if r.setting]
        if members:
            lines += settings_table(source, members) + [""]
            other = True
    if not other:
        lines += ["No runs with other settings.", ""]
    lines += ["## Sources", ""]
    for source in sources:
        lines += source_lines(source)
    return "\n".join(lines) + "\n"


def build_command(out: Path | None, dirs: Sequence[str]) -> str:
    parts = [COMMAND] + ([f"--out {display_path(out)}"] if out is not None else [])
    return " ".join(parts + [display_path(Path(d)) for d in dirs])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=COMMAND, description="Write the results page from run and sweep directories."
    )
    parser.add_argument("--out", type=Path, help="markdown file to write (default: stdout)")
    parser.add_argument("dirs", nargs="+", metavar="DIR", help="run or sweep directory")
    args = parser.parse_args(argv)
    try:
        sources = [load_source(Path(d)) for d in args.dirs]
        page = render(sources, build_command(args.out, args.dirs))
        if args.out is None:
            sys.stdout.write(page)
        else:
            try:
                args.out.parent.mkdir(parents=True, exist_ok=True)
                args.out.write_text(page)
            except OSError as exc:
                raise DataError(f"{args.out}: cannot write ({exc.strerror})") from None
            runs = sum(len(s.runs) for s in sources)
            print(f"wrote {args.out} ({runs} runs from {len(sources)} directories)")
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    return 0


if __name__ == "__main__":
    sys.exit(main())
