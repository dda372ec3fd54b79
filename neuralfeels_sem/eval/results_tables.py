"""Statistics and markdown tables of the results page (multi-material, single-material, settings)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from neuralfeels_sem.eval.aggregate import mean_and_std
from neuralfeels_sem.eval.results_runs import OBJECT_LAYOUT, Run, Source, get, oracles_of


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
    return mean_and_std(list(values))[0] if values else None


def std(values: Sequence[float]) -> float | None:
    """Sample standard deviation (n - 1); 0 for one value."""
    return mean_and_std(list(values))[1] if values else None


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


# Short names of the oracles for table cells (metrics.json names -> cell text).
ORACLE_SHORT = {
    "object_pose": "pose",
    "camera_mask": "mask",
    "tactile_contact_depth": "touch depth",
    "noise_free_depth": "clean depth",
    "material_labels": "labels",
}


def oracles_cell(run: Run) -> str:
    """The simulator ground truth a run used, in short names ("none" for a real rig's inputs)."""
    names, _ = oracles_of(run)
    if names is None:
        return "not recorded"
    return ", ".join(ORACLE_SHORT.get(n, n) for n in names) or "none"


def by_object_and_oracles(runs: Iterable[Run]) -> dict[tuple[str, str], list[Run]]:
    """Runs of one object are only pooled when they leaned on the same oracles."""
    return group_by(runs, lambda r: (r.object, oracles_cell(r)))


def group_by(runs: Iterable[Run], key) -> dict[Any, list[Run]]:
    groups: dict[Any, list[Run]] = {}
    for run in runs:
        groups.setdefault(key(run), []).append(run)
    return groups


def multi_material_table(runs: Sequence[Run]) -> list[str]:
    rows = []
    for (obj, oracles), members in by_object_and_oracles(runs).items():
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
                oracles,
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
            "oracles",
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


def single_material_table(
    runs: Sequence[Run], label: Callable[[Run], str] | None = None
) -> list[str]:
    """Classifier figures per object (or per `label(run)`, e.g. a setting) and oracles."""
    first = "object" if label is None else "setting"
    label = label or (lambda r: f"`{r.object}`")
    rows = []
    for (name, oracles), members in group_by(runs, lambda r: (label(r), oracles_cell(r))).items():
        rows.append(
            [
                name,
                oracles,
                str(len(members)),
                seeds_text(members),
                mean_std(values_of(members, "classifier_accuracy.overall", 100.0)),
                mean_std(values_of(members, "classifier_accuracy.coverage", 100.0)),
                mean_std(values_of(members, "classifier_accuracy.accuracy_all_touches", 100.0)),
                mean_std(values_of(members, "matching_pct")),
                mean_std(values_of(members, "fscore_5mm"), 3),
            ]
        )
    return table(
        [
            first,
            "oracles",
            "runs",
            "seeds",
            "classifier acc. on judged touches %",
            "coverage %",
            "acc. over all touches %",
            "map in the object's material %",
            "F-score @5 mm",
        ],
        rows,
    )


def setting_label(run: Run, keys: Sequence[str]) -> str:
    layout = get(run.metrics, OBJECT_LAYOUT)  # a custom mesh with a drawn layout
    if isinstance(layout, dict):
        head = f"{layout.get('mesh')}, layout {layout.get('layout_seed')}"
        keys = [k for k in keys if not k.startswith("object.")]  # the head names them
    else:
        head = f"object={run.object}"
    return ", ".join([head] + [f"{k}={run.setting[k]}" for k in keys if k in run.setting])


def range_cell(values: Sequence[float], digits: int = 0) -> str:
    """'low-high' over runs (one value when they agree); n/a when none recorded."""
    if not values:
        return "n/a"
    low, high = fmt(min(values), digits), fmt(max(values), digits)
    return low if low == high else f"{low}-{high}"


def per_seed_cell(runs: Sequence[Run]) -> str:
    return ", ".join(
        fmt(get(r.metrics, "matching_mean_class_pct"))
        for r in by_seed(runs)
        if get(r.metrics, "matching_mean_class_pct") is not None
    )


# What a run at sensor.pace=realtime gave up, shown where a table holds such a run.
# touch_frames: dropped frames whose touches were still fused (n/a: runs from before it).
PACE_COLUMNS = (
    ("frames", "frames mapped", 0),
    ("frames_dropped", "frames dropped", 0),
    ("touch_frames", "touch frames", 0),
)


def pace_cells(runs: Sequence[Run]) -> list[str]:
    cells = [range_cell(values_of(runs, key), digits) for key, _, digits in PACE_COLUMNS]
    return cells + [range_cell(values_of(runs, "lag_max_s"), 2)]


def settings_table(source: Source, runs: Sequence[Run]) -> list[str]:
    """One row per setting (object and the overrides that vary in this source)."""
    keys = sorted({k for r in runs for k in r.setting})
    varying = [k for k in keys if len({r.setting.get(k) for r in runs}) > 1]
    constant = [k for k in keys if k not in varying]
    lines = [f"### `{source.label}`", ""]
    if constant:
        fixed = ", ".join(f"`{k}={runs[0].setting[k]}`" for k in constant)
        lines += [f"Every run here: {fixed}.", ""]
    single = [r for r in runs if r.single_material]
    multi = [r for r in runs if not r.single_material]
    if single:  # a constant map scores 100 % there: the classifier's figures instead
        lines += single_material_table(single, lambda r: setting_label(r, varying))
        lines += [""] if multi else []
    return lines + (multi_setting_rows(multi, varying) if multi else [])


def multi_setting_rows(runs: Sequence[Run], varying: Sequence[str]) -> list[str]:
    """The settings table's rows for multi-material runs: matching beside the majority map."""
    with_pace = any(r.metrics.get("pace") == "realtime" for r in runs)
    rows = []
    # Runs of one setting pool only when they leaned on the same oracles, as in the object tables.
    groups = group_by(runs, lambda r: (setting_label(r, varying), oracles_cell(r)))
    for (label, oracles), members in groups.items():
        floor, _ = majority_cells(members)
        row = [
            label,
            oracles,
            seeds_text(members),
            per_seed_cell(members) or "n/a",
            "**" + mean_std(values_of(members, "matching_mean_class_pct")) + "**",
            floor,
            fmt(mean(margins(members)), sign=True),
            matching_cell(members),
            fmt(mean(values_of(members, "fscore_5mm")), 3),
            range_cell(values_of(members, "wall_s")),
        ]
        rows.append(row + (pace_cells(members) if with_pace else []))
    header = [
        "setting",
        "oracles",
        "seeds",
        "mean-class % per seed",
        "mean-class % (mean ± std)",
        "majority map % (material)",
        "margin",
        "matching % (majority)",
        "F-score @5 mm",
        "wall s",
    ]
    if with_pace:
        header += [name for _, name, _ in PACE_COLUMNS] + ["lag max s"]
    return table(header, rows)


PERCEPTION_KEYS = (
    ("perception.camera_mask_iou", "camera mask IoU", 3),
    ("perception.camera_frames_skipped", "camera frames skipped", 1),
    ("perception.tactile_contact_iou", "touch contact IoU", 3),
    ("perception.tactile_depth_mae_mm", "touch depth MAE mm", 3),
)


def perception_table(runs: Sequence[Run]) -> list[str]:
    """Per object and oracles: how well perception matched the simulator's ground truth."""
    rows = []
    for (obj, oracles), members in by_object_and_oracles(runs).items():
        # Camera figures only where the run segmented: with the simulator's mask nothing
        # was segmented, so no frame could be skipped either.
        segmented = [r for r in members if get(r.metrics, "perception.camera_mask") == "segment"]
        cells = [
            mean_std(
                values_of(segmented if key.startswith("perception.camera") else members, key),
                digits,
            )
            for key, _, digits in PERCEPTION_KEYS
        ]
        if any(c != "n/a" for c in cells):
            rows.append([f"`{obj}`", oracles, str(len(members)), *cells])
    header = ["object", "oracles", "runs"] + [name for _, name, _ in PERCEPTION_KEYS]
    return table(header, rows) if rows else []
