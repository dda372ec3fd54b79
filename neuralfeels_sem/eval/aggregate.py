"""End-of-sweep aggregate: one summary.json / summary.csv / summary.png per multirun.

Run by the Hydra callback `tasks/callbacks.py:SweepAggregator` in the launching process
after every job has finished, so it works with every launcher (basic, joblib, submitit,
ray). Jobs are grouped by the overrides that vary across the sweep, except `seed` (trials
of the same setting); each numeric metric gets mean and standard deviation per group. The
headline is mean-class matching beside the majority-material baseline and the margin
between them (`summary.txt` and the log show it per group; `matching_pct` never stands
alone).
"""

from __future__ import annotations

import csv
import json
import logging
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import yaml

log = logging.getLogger(__name__)

RESULT_FILES = ("metrics.json", "report.json", "info.json")
TRIAL_KEYS = ("seed",)
HEADLINE_METRICS = ("matching_mean_class_pct", "matching_pct", "test_accuracy", "fscore_5mm")
# Columns of summary.txt for mapping sweeps: (flattened metric, column title).
HEADLINE_COLUMNS = (
    ("matching_mean_class_pct", "mean-class %"),
    ("baseline_majority.matching_mean_class_pct", "majority %"),
    ("margin_over_majority.matching_mean_class_pct", "margin"),
    ("matching_pct", "matching %"),
    ("baseline_majority.matching_pct", "majority %"),
    ("matching_mesh_pct", "on mesh %"),
    ("classifier_accuracy.overall", "clf acc"),
    ("classifier_accuracy.coverage", "coverage"),
)


def flatten_numbers(data: Any, prefix: str = "") -> dict[str, float]:
    """Nested dict -> {'a.b': number}; lists and strings are skipped."""
    out: dict[str, float] = {}
    if isinstance(data, dict):
        for key, value in data.items():
            out.update(flatten_numbers(value, f"{prefix}{key}."))
    elif isinstance(data, bool):
        pass
    elif isinstance(data, int | float) and math.isfinite(float(data)):
        out[prefix[:-1]] = float(data)
    return out


def read_job(job_dir: Path) -> dict | None:
    overrides_file = job_dir / ".hydra" / "overrides.yaml"
    if not overrides_file.exists():
        return None
    overrides = [o for o in (yaml.safe_load(overrides_file.read_text()) or []) if "=" in o]
    job: dict[str, Any] = {
        "job": job_dir.name,
        "overrides": dict(o.lstrip("+~").split("=", 1) for o in overrides),
        "metrics": {},
        "status": "missing",
    }
    if (job_dir / "error.txt").exists():
        job["status"] = "failed"
        job["error"] = (job_dir / "error.txt").read_text().strip()
        return job
    for name in RESULT_FILES:
        path = job_dir / name
        if path.exists():
            try:
                job["metrics"] = flatten_numbers(json.loads(path.read_text()))
            except ValueError as exc:  # a truncated or corrupt file fails this job, not the summary
                job["status"] = "failed"
                job["error"] = f"{name} is unreadable: {exc}"
                return job
            job["status"] = "ok"
            break
    return job


def mean_and_std(values: list[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (n - 1; 0 for one value) of a non-empty list."""
    mean = sum(values) / len(values)
    var = sum((v - mean) ** 2 for v in values) / (len(values) - 1) if len(values) > 1 else 0.0
    return mean, math.sqrt(var)


def group_jobs(jobs: list[dict]) -> list[dict]:
    varying = sorted(
        {
            k
            for j in jobs
            for k in j["overrides"]
            if len({str(x["overrides"].get(k)) for x in jobs}) > 1
        }
        - set(TRIAL_KEYS)
    )
    buckets: dict[tuple, list[dict]] = defaultdict(list)
    for job in jobs:
        if job["status"] == "ok":
            buckets[tuple(str(job["overrides"].get(k)) for k in varying)].append(job)
    groups = []
    for key, members in sorted(buckets.items()):
        names = sorted({m for j in members for m in j["metrics"]})
        stats = {}
        for name in names:
            values = [j["metrics"][name] for j in members if name in j["metrics"]]
            mean, std = mean_and_std(values)
            stats[name] = {"mean": mean, "std": std, "n": len(values)}
        groups.append(
            {
                "group": dict(zip(varying, key)),
                "jobs": [j["job"] for j in members],
                "metrics": stats,
            }
        )
    return groups


def _job_order(path: Path) -> tuple:
    """Hydra's numbered job directories in number order (2 before 10), others after by name."""
    return (0, int(path.name), "") if path.name.isdigit() else (1, 0, path.name)


def summarize(sweep_dir: Path) -> dict:
    jobs = [
        j for d in sorted(sweep_dir.iterdir(), key=_job_order) if d.is_dir() and (j := read_job(d))
    ]
    summary = {
        "sweep_dir": str(sweep_dir),
        "jobs": jobs,
        "groups": group_jobs(jobs),
        "failed": [j["job"] for j in jobs if j["status"] != "ok"],
    }
    (sweep_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    write_csv(summary, sweep_dir / "summary.csv")
    table = headline_table(summary)
    if table:
        (sweep_dir / "summary.txt").write_text(table + "\n")
    plot_summary(summary, sweep_dir / "summary.png")
    return summary


def write_csv(summary: dict, path: Path) -> None:
    rows = []
    for group in summary["groups"]:
        for metric, s in group["metrics"].items():
            rows.append(
                {
                    **group["group"],
                    "metric": metric,
                    "mean": s["mean"],
                    "std": s["std"],
                    "n": s["n"],
                }
            )
    keys = sorted({k for g in summary["groups"] for k in g["group"]}) + [
        "metric",
        "mean",
        "std",
        "n",
    ]
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


def headline_table(summary: dict) -> str:
    """Per group: mean-class matching, the majority baseline, the margin and the rest (mean ± std).

    Empty when the sweep is not a mapping sweep. Classifier figures are 0-1 shares, shown in %.
    """
    groups = summary["groups"]
    if not any("matching_mean_class_pct" in g["metrics"] for g in groups):
        return ""
    names = [", ".join(f"{k}={v}" for k, v in g["group"].items()) or "all" for g in groups]
    width = max(len("setting"), *(len(n) for n in names))
    header = f"{'setting':<{width}}  {'n':>2}  " + "  ".join(
        f"{t:>13}" for _, t in HEADLINE_COLUMNS
    )
    lines = [header]
    for name, group in zip(names, groups):
        cells = []
        for key, _ in HEADLINE_COLUMNS:
            stat = group["metrics"].get(key)
            scale = 100.0 if key.startswith("classifier_accuracy.") else 1.0
            cells.append(
                "n/a" if stat is None else f"{scale * stat['mean']:.1f} ± {scale * stat['std']:.1f}"
            )
        n = max((s["n"] for s in group["metrics"].values()), default=0)
        lines.append(f"{name:<{width}}  {n:>2}  " + "  ".join(f"{c:>13}" for c in cells))
    return "\n".join(lines)


def plot_summary(summary: dict, path: Path) -> None:
    """Bar chart (mean +- std) of the headline metric per group."""
    groups = summary["groups"]
    if not groups:
        return
    available = {m for g in groups for m in g["metrics"]}
    metric = (
        next((m for m in HEADLINE_METRICS if m in available), None)
        or (sorted(available) or [None])[0]
    )
    if metric is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [", ".join(f"{k}={v}" for k, v in g["group"].items()) or "all" for g in groups]
    means = [g["metrics"].get(metric, {}).get("mean", float("nan")) for g in groups]
    stds = [g["metrics"].get(metric, {}).get("std", 0.0) for g in groups]
    fig, ax = plt.subplots(figsize=(max(4, 1.2 * len(groups) + 2), 4))
    ax.bar(range(len(groups)), means, yerr=stds, capsize=4, color="#4C72B0")
    floor_key = f"baseline_majority.{metric}"
    floors = [g["metrics"].get(floor_key, {}).get("mean") for g in groups]
    if any(f is not None for f in floors):
        ax.scatter(
            range(len(groups)),
            [float("nan") if f is None else f for f in floors],
            marker="_",
            s=900,
            color="black",
            zorder=3,
            label="majority-material map",
        )
        ax.legend(fontsize=8, loc="lower right")
    ax.set_xticks(range(len(groups)), labels, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(metric)
    ax.set_title(f"{metric} per group (mean ± std)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
