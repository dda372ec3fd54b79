"""Plots of a whole paper experiment (a `-m` sweep), drawn after the aggregate summary.

`plot_experiment` looks at what the jobs wrote (each job's metrics.json) and what the
sweep varied (the aggregate's groups), and draws what applies:
- `single_material_heatmap.png`, `single_material_bars.png`: classifier accuracy per
  finger x material over all jobs' touches pooled, each cell with its coverage (share of
  touches that got a label) and touch count, beside the accuracy over all touches
  (abstentions count as not correctly labelled); bars of the per-job mean ± std of
  accuracy, coverage and all-touch accuracy (figure 4A/4B);
- `matching_curves.png`: every run's mean-class and plain matching curves with the
  majority-material map's level, final mean ± std in the legend (figure 5A);
- `ablation.png`: headline metrics per group (mean ± std), clustered by object, with the
  majority-material map marked on the matching panels;
- `classifier_per_sensor.png`: from train/eval_classifier jobs' report.json, test accuracy
  per sensor (mean ± std over runs, as figure 3B).
Jobs that failed or lack files are skipped; a plot that cannot be drawn is logged, never raised.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from neuralfeels_sem.core.palette import class_colours

log = logging.getLogger(__name__)

FINGER_ORDER = ("index", "middle", "ring", "thumb")
# Headline metrics of ablation.png: (flattened key in summary.json, axis label, scale to display).
ABLATION_METRICS = (
    ("matching_mean_class_pct", "mean-class matching [%]", 1.0),
    ("matching_pct", "matching [%]", 1.0),
    ("fscore_5mm", "F-score @ 5 mm", 1.0),
    ("classifier_accuracy.overall", "classifier accuracy [%]", 100.0),
    ("test_accuracy", "test accuracy [%]", 100.0),
)


def _load_metrics(sweep_dir: Path, job: dict, name: str = "metrics.json") -> dict | None:
    if job.get("status") != "ok":
        return None
    path = sweep_dir / str(job.get("job")) / name
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _ordered(names: set[str], order: tuple[str, ...]) -> list[str]:
    return [n for n in order if n in names] + sorted(names - set(order))


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    fig.savefig(path, dpi=dpi)
    return path


def finger_material_table(
    runs: list[dict], figure: str = "accuracy"
) -> tuple[list[str], list[str], np.ndarray]:
    """(fingers, materials, values (F, M, runs) in %, NaN where a run has no value).

    `figure` is "accuracy" (on judged touches), "coverage" or "accuracy_all_touches"; the
    last two come from each run's per-cell counts (NaN for runs written without them).
    """
    tables = [r["classifier_accuracy"]["per_finger_material"] for r in runs]
    fingers = _ordered({f for t in tables for f in t}, FINGER_ORDER)
    materials = sorted({m for t in tables for row in t.values() for m in row})
    values = np.full((len(fingers), len(materials), len(tables)), np.nan)
    for k, (run, table) in enumerate(zip(runs, tables)):
        counts = run["classifier_accuracy"].get("counts") or {}
        for i, finger in enumerate(fingers):
            for j, material in enumerate(materials):
                if figure == "accuracy":
                    value = table.get(finger, {}).get(material)
                else:
                    value = (counts.get(finger, {}).get(material) or {}).get(figure)
                if value is not None:
                    values[i, j, k] = 100.0 * float(value)
    return fingers, materials, values


def pooled_finger_material(
    runs: list[dict], fingers: list[str], materials: list[str]
) -> dict[str, np.ndarray] | None:
    """Every run's touches pooled per finger x material: {'accuracy', 'coverage',
    'accuracy_all_touches'} in % and {'judged', 'touches'} counts, all (F, M); None when a
    run lacks the counts. A cell judged on 2 touches in one run must not weigh as much as
    one judged on 50 in another, as a mean of per-run accuracies makes it."""
    correct = np.zeros((len(fingers), len(materials)))
    judged = np.zeros_like(correct)
    touches = np.zeros_like(correct)
    for run in runs:
        counts = run["classifier_accuracy"].get("counts")
        if not isinstance(counts, dict):
            return None
        for i, finger in enumerate(fingers):
            for j, material in enumerate(materials):
                cell = counts.get(finger, {}).get(material) or {}
                correct[i, j] += float(cell.get("correct", 0))
                judged[i, j] += float(cell.get("judged", 0))
                touches[i, j] += float(cell.get("judged", 0)) + float(cell.get("abstentions", 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return {
            "accuracy": np.where(judged > 0, 100.0 * correct / judged, np.nan),
            "coverage": np.where(touches > 0, 100.0 * judged / touches, np.nan),
            "accuracy_all_touches": np.where(touches > 0, 100.0 * correct / touches, np.nan),
            "judged": judged,
            "touches": touches,
        }


def _mean_std(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and sample std over the last axis, ignoring NaN (std 0 with one value)."""
    count = (~np.isnan(values)).sum(axis=2)
    with np.errstate(invalid="ignore"):
        mean = np.where(count > 0, np.nansum(values, axis=2) / np.maximum(count, 1), np.nan)
        sq = np.nansum((values - mean[..., None]) ** 2, axis=2)
        std = np.where(count > 1, np.sqrt(sq / np.maximum(count - 1, 1)), 0.0)
    return mean, std


def _heatmap(
    ax, shown: np.ndarray, texts: list[list[str]], fingers, materials, title: str, ylabel=True
):
    image = ax.imshow(np.ma.masked_invalid(shown), cmap="viridis", vmin=0, vmax=100)
    for i in range(len(fingers)):
        for j in range(len(materials)):
            colour = "white" if np.isnan(shown[i, j]) or shown[i, j] < 60 else "black"
            ax.text(j, i, texts[i][j], ha="center", va="center", color=colour, fontsize=8)
    ax.set_xticks(range(len(materials)), materials)
    ax.set_yticks(range(len(fingers)), fingers)
    ax.set_xlabel("material")
    if ylabel:
        ax.set_ylabel("DIGIT sensor")
    ax.set_title(title, fontsize=9)
    return image


def plot_finger_material(runs: list[dict], out_dir: Path, dpi: int = 120) -> list[Path]:
    fingers, materials, values = finger_material_table(runs)
    if not fingers or not materials:
        return []
    pooled = pooled_finger_material(runs, fingers, materials)

    def cell(value: float, extra: str = "") -> str:
        return "n/a" if np.isnan(value) else f"{value:.0f}%{extra}"

    fig = Figure(figsize=(2.6 * len(materials) + 3.0, 0.9 * len(fingers) + 1.8))
    if pooled is None:  # runs written before counts existed: per-run accuracies only
        mean, _ = _mean_std(values)
        ax = fig.add_subplot()
        texts = [[cell(mean[i, j]) for j in range(len(materials))] for i in range(len(fingers))]
        title = f"Accuracy on judged touches, mean of {len(runs)} runs"
        image = _heatmap(ax, mean, texts, fingers, materials, title)
    else:
        left, right = fig.subplots(1, 2)
        texts = [
            [
                cell(pooled["accuracy"][i, j])
                + (
                    ""
                    if np.isnan(pooled["coverage"][i, j])
                    else f"\ncov {pooled['coverage'][i, j]:.0f}%"
                )
                + f"\nn={int(pooled['touches'][i, j])}"
                for j in range(len(materials))
            ]
            for i in range(len(fingers))
        ]
        title = f"Accuracy on judged touches, coverage\n(touches of {len(runs)} runs pooled)"
        image = _heatmap(left, pooled["accuracy"], texts, fingers, materials, title)
        all_touch = pooled["accuracy_all_touches"]
        texts = [
            [cell(all_touch[i, j]) for j in range(len(materials))] for i in range(len(fingers))
        ]
        title = "Accuracy over all touches\n(an abstention counts as not correct)"
        _heatmap(right, all_touch, texts, fingers, materials, title, ylabel=False)
    fig.colorbar(image, ax=fig.axes, label="[%]")
    paths = [_save(fig, out_dir / "single_material_heatmap.png", dpi)]

    panels = [("accuracy", "accuracy on judged touches [%]")]
    if pooled is not None:
        panels += [
            ("coverage", "coverage [%]"),
            ("accuracy_all_touches", "accuracy over all touches [%]"),
        ]
    fig = Figure(figsize=(max(5.0, 1.6 * len(fingers) + 2.0), 2.6 * len(panels) + 1.2))
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    width = 0.8 / len(materials)
    colours = class_colours(materials) / 255.0
    x = np.arange(len(fingers))
    for ax, (figure, label) in zip(axes, panels):
        mean, std = _mean_std(finger_material_table(runs, figure)[2])
        for j, material in enumerate(materials):
            ax.bar(
                x + (j - (len(materials) - 1) / 2) * width,
                np.nan_to_num(mean[:, j]),
                width,
                yerr=std[:, j],
                capsize=3,
                color=colours[j],
                edgecolor="black",
                linewidth=0.5,
                label=material,
            )
        ax.set_xticks(x, fingers)
        ax.set_ylim(0, 105)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_title("Classifier per sensor and material (mean ± std over runs)")
    axes[-1].legend(
        fontsize=8, ncol=len(materials), loc="upper center", bbox_to_anchor=(0.5, -0.15)
    )
    fig.tight_layout()
    paths.append(_save(fig, out_dir / "single_material_bars.png", dpi))
    return paths


def _setting(job: dict, varying: list[str]) -> str:
    overrides = job.get("overrides", {})
    parts = [f"{k.split('.')[-1]}={overrides[k]}" for k in varying if k in overrides]
    return ", ".join(parts) or "all runs"


# The two panels of matching_curves.png: (final metric, curve, majority key, axis label).
CURVE_PANELS = (
    (
        "matching_mean_class_pct",
        "matching_mean_class_curve",
        "matching_mean_class_pct",
        "mean-class matching [%]",
    ),
    ("matching_pct", "matching_curve", "matching_pct", "matching [%]"),
)


def _final(metrics: dict, key: str, curve_key: str) -> float | None:
    if metrics.get(key) is not None:
        return float(metrics[key])
    curve = metrics.get(curve_key) or []
    return float(curve[-1][2]) if curve else None


def plot_runs_matching(
    runs: list[tuple[dict, dict]], varying: list[str], path: Path, dpi: int = 120
) -> Path:
    """Every run's mean-class and plain matching curves, one colour per setting, with the
    majority-material map's level dashed; final mean ± std per setting in the legends."""
    by_setting: dict[str, list[tuple[dict, dict]]] = {}
    for job, metrics in runs:
        by_setting.setdefault(_setting(job, varying), []).append((job, metrics))
    panels = [p for p in CURVE_PANELS if any(m.get(p[1]) for _, m in runs)]
    fig = Figure(figsize=(6.0 * len(panels), 4.4), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, (key, curve_key, floor_key, label) in zip(axes, panels):
        for k, (name, members) in enumerate(sorted(by_setting.items())):
            colour = f"C{k % 10}"
            finals = [f for _, m in members if (f := _final(m, key, curve_key)) is not None]
            std = float(np.std(finals, ddof=1)) if len(finals) > 1 else 0.0
            text = (
                f"{name}: {np.mean(finals):.1f} ± {std:.1f}% (n={len(finals)})" if finals else name
            )
            for i, (_, metrics) in enumerate(members):
                curve = np.asarray(metrics.get(curve_key) or [], dtype=np.float64).reshape(-1, 3)
                ax.plot(
                    curve[:, 1],
                    curve[:, 2],
                    color=colour,
                    marker="o",
                    markersize=3,
                    alpha=0.85,
                    label=text if i == 0 else None,
                )
            floors = [
                float(m["baseline_majority"][floor_key])
                for _, m in members
                if (m.get("baseline_majority") or {}).get(floor_key) is not None
            ]
            if floors:
                ax.axhline(
                    np.mean(floors),
                    color=colour,
                    linestyle="--",
                    linewidth=1,
                    label=f"{name}: majority map {np.mean(floors):.1f}%",
                )
        ax.set_xlabel("sensor time [s]")
        ax.set_ylabel(label)
        ax.set_ylim(0, 100)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_title("Matching over time (dashed: the majority-material map)")
    return _save(fig, path, dpi)


def plot_groups(summary: dict, path: Path, dpi: int = 120) -> Path | None:
    """Grouped bars (mean ± std) of the headline metrics: clusters = objects, bars = the other axes."""
    groups = summary.get("groups") or []
    if len(groups) < 2:
        return None
    metrics = [m for m in ABLATION_METRICS if any(m[0] in g.get("metrics", {}) for g in groups)]
    if not metrics:
        return None
    keys = sorted({k for g in groups for k in g.get("group", {})})
    axis_keys = [k for k in keys if k != "object"]

    def setting(g: dict) -> str:
        return ", ".join(f"{k.split('.')[-1]}={g['group'].get(k)}" for k in axis_keys) or "all"

    # Without an object axis, name the one object the jobs share (else "all").
    objects = {str(j.get("overrides", {}).get("object")) for j in summary.get("jobs") or []}
    fixed = objects.pop() if len(objects) == 1 and "None" not in objects else "all"
    clusters = sorted({str(g["group"].get("object", fixed)) for g in groups})
    settings = sorted({setting(g) for g in groups})
    fig = Figure(
        figsize=(
            max(5.0, 1.5 * len(clusters) * max(1, len(settings)) ** 0.5 + 2.5),
            3.0 * len(metrics) + 0.3 * len(settings),
        ),
        layout="constrained",
    )
    axes = fig.subplots(len(metrics), 1, squeeze=False)[:, 0]
    width = 0.8 / len(settings)
    x = np.arange(len(clusters))
    for ax, (key, label, scale) in zip(axes, metrics):
        for s, name in enumerate(settings):
            means, stds = np.full(len(clusters), np.nan), np.zeros(len(clusters))
            for g in groups:
                if setting(g) == name and key in g.get("metrics", {}):
                    c = clusters.index(str(g["group"].get("object", fixed)))
                    means[c] = scale * g["metrics"][key]["mean"]
                    stds[c] = scale * g["metrics"][key]["std"]
            offset = x + (s - (len(settings) - 1) / 2) * width
            ax.bar(
                offset,
                np.nan_to_num(means),
                width,
                yerr=stds,
                capsize=3,
                label=name,
                edgecolor="black",
                linewidth=0.5,
            )
            floors = np.full(len(clusters), np.nan)
            for g in groups:
                floor = g.get("metrics", {}).get(f"baseline_majority.{key}")
                if setting(g) == name and floor is not None:
                    floors[clusters.index(str(g["group"].get("object", fixed)))] = (
                        scale * floor["mean"]
                    )
            if not np.isnan(floors).all():
                ax.scatter(
                    offset,
                    floors,
                    marker="_",
                    s=300,
                    color="black",
                    zorder=3,
                    label="majority-material map" if s == 0 else None,
                )
        ax.set_xticks(x, clusters)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_title("Comparison per setting (mean ± std over trials)")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", fontsize=8)
    return _save(fig, path, dpi)


def plot_classifier_sensors(reports: list[dict], path: Path, dpi: int = 120) -> Path | None:
    """Test accuracy per DIGIT sensor over classifier runs (mean ± std), as the paper's figure 3B."""
    per_sensor = [r["per_sensor"] for r in reports]
    sensors = _ordered({s for p in per_sensor for s in p}, FINGER_ORDER)
    if not sensors:
        return None
    values = [[100.0 * float(p[s]) for p in per_sensor if p.get(s) is not None] for s in sensors]
    means = [float(np.mean(v)) if v else np.nan for v in values]
    stds = [float(np.std(v, ddof=1)) if len(v) > 1 else 0.0 for v in values]
    fig = Figure(figsize=(max(4.5, 1.1 * len(sensors) + 2.0), 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.bar(range(len(sensors)), np.nan_to_num(means), yerr=stds, capsize=4, color="#4C72B0")
    for i, m in enumerate(means):
        if not np.isnan(m):
            ax.text(
                i,
                min(m, 100.0) / 2,
                f"{m:.1f}",
                ha="center",
                va="center",
                color="white",
                fontsize=9,
            )
    ax.set_xticks(range(len(sensors)), sensors)
    ax.set_ylim(0, 105)
    ax.set_ylabel("test accuracy [%]")
    ax.grid(axis="y", alpha=0.3)
    ax.set_title(f"Classifier accuracy per sensor ({len(reports)} runs, mean ± std)")
    return _save(fig, path, dpi)


def plot_experiment(summary: dict, sweep_dir: Path, dpi: int = 120) -> list[Path]:
    """Draw every experiment plot that the sweep's results support; returns the files written."""
    sweep_dir = Path(sweep_dir)
    jobs = summary.get("jobs") or []
    loaded = [(job, m) for job in jobs if (m := _load_metrics(sweep_dir, job)) is not None]
    varying = sorted({k for g in summary.get("groups") or [] for k in g.get("group", {})})
    written: list[Path] = []

    def attempt(name: str, draw) -> None:
        try:
            result = draw()
        except Exception:  # a broken plot must not lose the summary or the other plots
            log.exception("sweep plot %s failed", name)
            return
        if result:
            written.extend(result if isinstance(result, list) else [result])

    with_table = [
        m
        for _, m in loaded
        if isinstance(m.get("classifier_accuracy"), dict)
        and m["classifier_accuracy"].get("per_finger_material")
    ]
    if with_table:
        attempt("single_material", lambda: plot_finger_material(with_table, sweep_dir, dpi))
    with_curve = [(j, m) for j, m in loaded if m.get("matching_curve")]
    if with_curve:
        attempt(
            "matching_curves",
            lambda: plot_runs_matching(with_curve, varying, sweep_dir / "matching_curves.png", dpi),
        )
    attempt("ablation", lambda: plot_groups(summary, sweep_dir / "ablation.png", dpi))
    reports = [
        r for job in jobs if isinstance(r := _load_metrics(sweep_dir, job, "report.json"), dict)
    ]
    reports = [r for r in reports if isinstance(r.get("per_sensor"), dict) and r["per_sensor"]]
    if reports:
        sensors_png = sweep_dir / "classifier_per_sensor.png"
        attempt("classifier_per_sensor", lambda: plot_classifier_sensors(reports, sensors_png, dpi))
    for written_path in written:
        log.info("wrote %s", written_path)
    return written


__all__ = [
    "plot_classifier_sensors",
    "plot_experiment",
    "finger_material_table",
    "pooled_finger_material",
    "plot_finger_material",
    "plot_groups",
    "plot_runs_matching",
]
