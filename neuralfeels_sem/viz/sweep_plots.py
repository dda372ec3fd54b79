"""Plots of a whole paper experiment (a `-m` sweep), drawn after the aggregate summary.

`plot_experiment` looks at what the jobs wrote (each job's metrics.json) and what the
sweep varied (the aggregate's groups), and draws what applies:
- `single_material_heatmap.png`, `single_material_bars.png`: classifier accuracy per
  finger x material over all jobs' touches pooled (with the touch count; the mean over
  jobs when they lack counts), and bars of the per-job mean ± std (figure 4A/4B);
- `matching_curves.png`: every run's matching curve, final mean ± std in the title (figure 5A);
- `ablation.png`: headline metrics per group (mean ± std), clustered by object;
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

from neuralfeels_sem.viz.palette import class_colours

log = logging.getLogger(__name__)

FINGER_ORDER = ("index", "middle", "ring", "thumb")
# Headline metrics of ablation.png: (flattened key in summary.json, axis label, scale to display).
ABLATION_METRICS = (
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


def finger_material_table(runs: list[dict]) -> tuple[list[str], list[str], np.ndarray]:
    """(fingers, materials, values (F, M, runs) in %, NaN where a run has no value)."""
    tables = [r["classifier_accuracy"]["per_finger_material"] for r in runs]
    fingers = _ordered({f for t in tables for f in t}, FINGER_ORDER)
    materials = sorted({m for t in tables for row in t.values() for m in row})
    values = np.full((len(fingers), len(materials), len(tables)), np.nan)
    for k, table in enumerate(tables):
        for i, finger in enumerate(fingers):
            for j, material in enumerate(materials):
                value = table.get(finger, {}).get(material)
                if value is not None:
                    values[i, j, k] = 100.0 * float(value)
    return fingers, materials, values


def pooled_finger_material(
    runs: list[dict], fingers: list[str], materials: list[str]
) -> tuple[np.ndarray, np.ndarray] | None:
    """(accuracy % (F, M), judged touches (F, M)) over all runs' touches pooled; None
    when a run lacks the counts. A cell judged on 2 touches in one run must not weigh
    as much as one judged on 50 in another, as a mean of per-run accuracies makes it."""
    correct = np.zeros((len(fingers), len(materials)))
    judged = np.zeros_like(correct)
    for run in runs:
        counts = run["classifier_accuracy"].get("counts")
        if not isinstance(counts, dict):
            return None
        for i, finger in enumerate(fingers):
            for j, material in enumerate(materials):
                cell = counts.get(finger, {}).get(material) or {}
                correct[i, j] += float(cell.get("correct", 0))
                judged[i, j] += float(cell.get("judged", 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(judged > 0, 100.0 * correct / judged, np.nan), judged


def plot_finger_material(runs: list[dict], out_dir: Path, dpi: int = 120) -> list[Path]:
    fingers, materials, values = finger_material_table(runs)
    if not fingers or not materials:
        return []
    seen = ~np.isnan(values)
    count = seen.sum(axis=2)
    with np.errstate(invalid="ignore"):
        mean = np.where(count > 0, np.nansum(values, axis=2) / np.maximum(count, 1), np.nan)
        sq = np.nansum((values - mean[..., None]) ** 2, axis=2)
        std = np.where(count > 1, np.sqrt(sq / np.maximum(count - 1, 1)), 0.0)

    pooled = pooled_finger_material(runs, fingers, materials)
    shown, title = mean, f"Classifier accuracy [%], mean of {len(runs)} runs"
    if pooled is not None:
        shown, title = pooled[0], f"Classifier accuracy [%], touches of {len(runs)} runs pooled"
    fig = Figure(figsize=(1.3 * len(materials) + 2.5, 0.8 * len(fingers) + 1.6))
    ax = fig.add_subplot()
    image = ax.imshow(np.ma.masked_invalid(shown), cmap="viridis", vmin=0, vmax=100)
    for i in range(len(fingers)):
        for j in range(len(materials)):
            text = "n/a" if np.isnan(shown[i, j]) else f"{shown[i, j]:.0f}"
            if pooled is not None and not np.isnan(shown[i, j]):
                text += f"\nn={int(pooled[1][i, j])}"
            colour = "white" if np.isnan(shown[i, j]) or shown[i, j] < 60 else "black"
            ax.text(j, i, text, ha="center", va="center", color=colour, fontsize=10)
    ax.set_xticks(range(len(materials)), materials)
    ax.set_yticks(range(len(fingers)), fingers)
    ax.set_xlabel("material")
    ax.set_ylabel("DIGIT sensor")
    ax.set_title(title)
    fig.colorbar(image, ax=ax, label="accuracy [%]")
    fig.tight_layout()
    paths = [_save(fig, out_dir / "single_material_heatmap.png", dpi)]

    fig = Figure(figsize=(max(5.0, 1.6 * len(fingers) + 2.0), 3.8))
    ax = fig.add_subplot()
    width = 0.8 / len(materials)
    colours = class_colours(materials) / 255.0
    x = np.arange(len(fingers))
    for j, material in enumerate(materials):
        heights = np.nan_to_num(mean[:, j])
        ax.bar(
            x + (j - (len(materials) - 1) / 2) * width,
            heights,
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
    ax.set_ylabel("accuracy [%]")
    ax.set_title("Classifier accuracy per sensor (mean ± std over runs)")
    ax.legend(fontsize=8, ncol=len(materials), loc="lower center", bbox_to_anchor=(0.5, -0.3))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    paths.append(_save(fig, out_dir / "single_material_bars.png", dpi))
    return paths


def _setting(job: dict, varying: list[str]) -> str:
    overrides = job.get("overrides", {})
    parts = [f"{k.split('.')[-1]}={overrides[k]}" for k in varying if k in overrides]
    return ", ".join(parts) or "all runs"


def _final(metrics: dict) -> float:
    if metrics.get("matching_pct") is not None:
        return float(metrics["matching_pct"])
    return float(metrics["matching_curve"][-1][2])


def plot_runs_matching(
    runs: list[tuple[dict, dict]], varying: list[str], path: Path, dpi: int = 120
) -> Path:
    """Every run's matching curve, one colour per setting; final mean ± std per setting."""
    by_setting: dict[str, list[tuple[dict, dict]]] = {}
    for job, metrics in runs:
        by_setting.setdefault(_setting(job, varying), []).append((job, metrics))
    fig = Figure(figsize=(6.5, 4.2), layout="constrained")
    ax = fig.add_subplot()
    colours = [f"C{i % 10}" for i in range(len(by_setting))]
    summaries = []
    for colour, (name, members) in zip(colours, sorted(by_setting.items())):
        finals = [_final(m) for _, m in members]
        std = float(np.std(finals, ddof=1)) if len(finals) > 1 else 0.0
        summaries.append((np.mean(finals), std, len(finals)))
        label = f"{name}: {np.mean(finals):.1f} ± {std:.1f}% (n={len(finals)})"
        for k, (_, metrics) in enumerate(members):
            curve = np.asarray(metrics["matching_curve"], dtype=np.float64).reshape(-1, 3)
            ax.plot(
                curve[:, 1],
                curve[:, 2],
                color=colour,
                marker="o",
                markersize=3,
                alpha=0.85,
                label=label if k == 0 else None,
            )
    ax.set_xlabel("sensor time [s]")
    ax.set_ylabel("matching [%]")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    if len(summaries) == 1:
        mean, std, n = summaries[0]
        ax.set_title(f"Matching over time: final {mean:.2f} ± {std:.2f}% ({n} runs)")
    else:
        ax.set_title("Matching over time per setting (final mean ± std)")
    fig.legend(loc="outside lower center", fontsize=8, ncol=1)
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
            ax.bar(
                x + (s - (len(settings) - 1) / 2) * width,
                np.nan_to_num(means),
                width,
                yerr=stds,
                capsize=3,
                label=name,
                edgecolor="black",
                linewidth=0.5,
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
