"""Plots of a whole paper experiment (a `-m` sweep), drawn after the aggregate summary.

`plot_experiment` looks at what the jobs wrote (each job's metrics.json) and what the
sweep varied (the aggregate's groups), and draws what applies:
- `single_material_heatmap.png`, `single_material_bars.png`: classifier accuracy per
  finger x material over all jobs' touches pooled, each cell with its coverage (share of
  touches that got a label) and touch count, beside the accuracy over all touches
  (abstentions count as not correctly labelled); bars of the per-job mean ± std of
  accuracy, coverage and all-touch accuracy (figure 4A/4B);
- `matching_curves.png`: every run's mean-class and plain matching curves with the
  majority-material map's level, final mean ± std in the legend (figure 5A); above
  CROWDED_SETTINGS settings each run thin, the mean bold and the lowest finals named;
- `ablation.png`: headline metrics per group (mean ± std), clustered by object (one
  object: a bar per setting along the axis), with the majority-material map marked on
  the matching panels;
- `classifier_per_sensor.png`: from train/eval_classifier jobs' report.json, test accuracy
  per sensor (mean ± std over runs, as figure 3B);
- `maps_grid.png`: every mapping job's final material map (its material_maps.png) with
  its setting and mean-class matching beside the majority map's (maps_grid.py);
- `pose_curves.png`: every tracked run's pose error over time, per object
  (pose_sweep_plot.py).
Jobs that failed or lack files are skipped; a plot that cannot be drawn is logged, never raised.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from neuralfeels_sem.viz.finger_material_plots import FINGER_ORDER, ordered, plot_finger_material
from neuralfeels_sem.viz.maps_grid import MAPS_FILE, MapTile, plot_maps_grid, tile_title
from neuralfeels_sem.viz.pose_sweep_plot import plot_pose_curves

log = logging.getLogger(__name__)

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


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    fig.savefig(path, dpi=dpi)
    return path


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


# Above this many settings the curves are not told apart by colour and legend: each run is
# a thin line, the mean over runs bold, and the lowest finals are named at their ends.
CROWDED_SETTINGS = 8


def plot_runs_matching(
    runs: list[tuple[dict, dict]], varying: list[str], path: Path, dpi: int = 120
) -> Path:
    """Every run's mean-class and plain matching curves, one colour per setting, with the
    majority-material map's level dashed; final mean ± std per setting in the legends
    (above CROWDED_SETTINGS settings: the mean over runs and the lowest runs named)."""
    by_setting: dict[str, list[tuple[dict, dict]]] = {}
    for job, metrics in runs:
        by_setting.setdefault(_setting(job, varying), []).append((job, metrics))
    panels = [p for p in CURVE_PANELS if any(m.get(p[1]) for _, m in runs)]
    fig = Figure(figsize=(6.0 * len(panels), 4.4), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    draw = _draw_crowded if len(by_setting) > CROWDED_SETTINGS else _draw_per_setting
    for ax, panel in zip(axes, panels):
        draw(ax, sorted(by_setting.items()), panel)
        ax.set_xlabel("sensor time [s]")
        ax.set_ylabel(panel[3])
        ax.set_ylim(0, 100)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_title("Matching over time (dashed: the majority-material map)")
    return _save(fig, path, dpi)


def _curve(metrics: dict, curve_key: str) -> np.ndarray:
    """(n, 3) rows of frame, sensor time, matching."""
    return np.asarray(metrics.get(curve_key) or [], dtype=np.float64).reshape(-1, 3)


def _floors(members: list[tuple[dict, dict]], floor_key: str) -> list[float]:
    return [
        float(m["baseline_majority"][floor_key])
        for _, m in members
        if (m.get("baseline_majority") or {}).get(floor_key) is not None
    ]


def _draw_per_setting(ax, settings: list[tuple[str, list]], panel: tuple) -> None:
    """Each setting in its colour, its final mean ± std and its majority map in the legend."""
    key, curve_key, floor_key, _ = panel
    for k, (name, members) in enumerate(settings):
        colour = f"C{k % 10}"
        finals = [f for _, m in members if (f := _final(m, key, curve_key)) is not None]
        std = float(np.std(finals, ddof=1)) if len(finals) > 1 else 0.0
        text = f"{name}: {np.mean(finals):.1f} ± {std:.1f}% (n={len(finals)})" if finals else name
        for i, (_, metrics) in enumerate(members):
            curve = _curve(metrics, curve_key)
            ax.plot(curve[:, 1], curve[:, 2], color=colour, marker="o", markersize=3,
                    alpha=0.85, label=text if i == 0 else None)  # fmt: skip
        if floors := _floors(members, floor_key):
            ax.axhline(np.mean(floors), color=colour, linestyle="--", linewidth=1,
                       label=f"{name}: majority map {np.mean(floors):.1f}%")  # fmt: skip


def _draw_crowded(ax, settings: list[tuple[str, list]], panel: tuple, named: int = 3) -> None:
    """Every run thin, the mean curve over runs bold, the mean majority map dashed, and the
    `named` lowest finals labelled with their setting at the curve's end."""
    key, curve_key, floor_key, _ = panel
    curves, finals = [], []
    for k, (name, members) in enumerate(settings):
        colour = _spread_colour(k, len(settings))
        for _, metrics in members:
            curve = _curve(metrics, curve_key)
            if len(curve):
                ax.plot(curve[:, 1], curve[:, 2], color=colour, linewidth=0.8, alpha=0.6)
                curves.append(curve)
            if (final := _final(metrics, key, curve_key)) is not None and len(curve):
                finals.append((final, name, float(curve[-1, 1])))
    if curves:
        times = np.unique(np.concatenate([c[:, 1] for c in curves]))
        mean = np.mean([np.interp(times, c[:, 1], c[:, 2]) for c in curves], axis=0)
        values = [f for f, _, _ in finals]
        ax.plot(times, mean, color="black", linewidth=2.2,
                label=f"mean of {len(curves)} runs: final {np.mean(values):.1f} ± "
                f"{np.std(values, ddof=1) if len(values) > 1 else 0.0:.1f}%")  # fmt: skip
    if floors := _floors([m for _, members in settings for m in members], floor_key):
        ax.axhline(np.mean(floors), color="black", linestyle="--", linewidth=1,
                   label=f"majority map, mean {np.mean(floors):.1f}%")  # fmt: skip
    label_y = -np.inf
    for final, name, end in sorted(finals)[:named]:
        label_y = max(final, label_y + 4.0)  # close finals: each label 4 points above the last
        ax.annotate(f"{name}: {final:.1f}%", (end, final), (end - 0.3, label_y - 2.0),
                    fontsize=7, ha="right", va="center")  # fmt: skip


def _spread_colour(k: int, n: int) -> tuple:
    """The k-th of n colours spread over viridis (distinct beyond the 10 cycle colours)."""
    return colormaps["viridis"](k / max(1, n - 1))


def _group_setting(g: dict, axis_keys: list[str]) -> str:
    """A group's label over the non-object axes, e.g. ``lr=0.1, seed=2`` (``all`` without axes)."""
    return ", ".join(f"{k.split('.')[-1]}={g['group'].get(k)}" for k in axis_keys) or "all"


def _group_clusters(summary: dict, groups: list[dict]) -> tuple[str, list[str]]:
    """The object shown when a group has no object axis, and the sorted object clusters."""
    # Without an object axis, name the one object the jobs share (else "all").
    objects = {str(j.get("overrides", {}).get("object")) for j in summary.get("jobs") or []}
    fixed = objects.pop() if len(objects) == 1 and "None" not in objects else "all"
    clusters = sorted({str(g["group"].get("object", fixed)) for g in groups})
    return fixed, clusters


def _draw_group_metric(
    ax,
    groups: list[dict],
    metric: tuple,
    clusters: list[str],
    settings: list[str],
    setting,
    cluster_of,
) -> None:
    """One metric's panel: a bar per setting in each cluster, plus the majority-map floor."""
    key, label, scale = metric
    width = 0.8 / len(settings)
    x = np.arange(len(clusters))
    for s, name in enumerate(settings):
        means, stds = np.full(len(clusters), np.nan), np.zeros(len(clusters))
        for g in groups:
            if setting(g) == name and key in g.get("metrics", {}):
                c = clusters.index(cluster_of(g))
                means[c] = scale * g["metrics"][key]["mean"]
                stds[c] = scale * g["metrics"][key]["std"]
        offset = x + (s - (len(settings) - 1) / 2) * width
        ax.bar(
            offset,
            np.nan_to_num(means),
            width,
            yerr=stds,
            capsize=3,
            label=None if name == "all" else name,  # one unnamed series needs no legend
            edgecolor="black",
            linewidth=0.5,
        )
        floors = np.full(len(clusters), np.nan)
        for g in groups:
            floor = g.get("metrics", {}).get(f"baseline_majority.{key}")
            if setting(g) == name and floor is not None:
                floors[clusters.index(cluster_of(g))] = scale * floor["mean"]
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
    slanted = len(clusters) > 6
    ax.set_xticks(x, clusters, rotation=40 if slanted else 0, ha="right" if slanted else "center")
    ax.set_ylabel(label)
    ax.grid(axis="y", alpha=0.3)


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

    fixed, clusters = _group_clusters(summary, groups)

    def setting(g: dict) -> str:
        return _group_setting(g, axis_keys)

    def cluster_of(g: dict) -> str:
        return str(g["group"].get("object", fixed))

    if len(clusters) == 1:  # one object: the settings along the axis, not told by colour
        clusters, cluster_of, setting = sorted({setting(g) for g in groups}), setting, cluster_of
    settings = sorted({setting(g) for g in groups})
    per_cluster = min(1.5 * len(settings) ** 0.5, 0.3 + 0.45 * len(settings))
    fig = Figure(
        figsize=(
            max(5.0, per_cluster * len(clusters) + 2.5),
            3.0 * len(metrics) + 0.3 * len(settings),
        ),
        layout="constrained",
    )
    axes = fig.subplots(len(metrics), 1, squeeze=False)[:, 0]
    for ax, metric in zip(axes, metrics):
        _draw_group_metric(ax, groups, metric, clusters, settings, setting, cluster_of)
    axes[0].set_title("Comparison per setting (mean ± std over trials)")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", fontsize=8)
    return _save(fig, path, dpi)


def plot_classifier_sensors(reports: list[dict], path: Path, dpi: int = 120) -> Path | None:
    """Test accuracy per DIGIT sensor over classifier runs (mean ± std), as the paper's figure 3B."""
    per_sensor = [r["per_sensor"] for r in reports]
    sensors = ordered({s for p in per_sensor for s in p}, FINGER_ORDER)
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
    pose_png = sweep_dir / "pose_curves.png"
    attempt("pose_curves", lambda: plot_pose_curves(loaded, varying, pose_png, dpi))
    reports = [
        r for job in jobs if isinstance(r := _load_metrics(sweep_dir, job, "report.json"), dict)
    ]
    reports = [r for r in reports if isinstance(r.get("per_sensor"), dict) and r["per_sensor"]]
    if reports:
        sensors_png = sweep_dir / "classifier_per_sensor.png"
        attempt("classifier_per_sensor", lambda: plot_classifier_sensors(reports, sensors_png, dpi))
    tiles = [
        MapTile(picture, tile_title(_setting(job, varying), m))
        for job, m in loaded
        if (picture := sweep_dir / str(job.get("job")) / MAPS_FILE).is_file()
    ]
    if tiles:
        grid_png = sweep_dir / "maps_grid.png"
        attempt("maps_grid", lambda: plot_maps_grid(tiles, grid_png, dpi=dpi))
    for written_path in written:
        log.info("wrote %s", written_path)
    return written


__all__ = [
    "plot_classifier_sensors",
    "plot_experiment",
    "plot_finger_material",
    "plot_groups",
    "plot_maps_grid",
    "plot_runs_matching",
]
