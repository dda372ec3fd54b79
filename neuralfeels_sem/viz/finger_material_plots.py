"""Figure 4 of a sweep: the classifier per DIGIT and material, pooled over the jobs' touches.

`single_material_heatmap.png`: accuracy on judged touches with each cell's coverage and
touch count, beside the accuracy over all touches (an abstention counts as not correct);
`single_material_bars.png`: per-job mean ± std of accuracy, coverage and all-touch accuracy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from neuralfeels_sem.core.palette import class_colours
from neuralfeels_sem.utils.atomic import atomic_write

FINGER_ORDER = ("index", "middle", "ring", "thumb")


def ordered(names: set[str], order: tuple[str, ...]) -> list[str]:
    """`names` in `order` first, then the rest sorted."""
    return [n for n in order if n in names] + sorted(names - set(order))


def finger_material_table(
    runs: list[dict], figure: str = "accuracy"
) -> tuple[list[str], list[str], np.ndarray]:
    """(fingers, materials, values (F, M, runs) in %, NaN where a run has no value).

    `figure` is "accuracy" (on judged touches), "coverage" or "accuracy_all_touches"; the
    last two come from each run's per-cell counts (NaN for runs written without them).
    """
    tables = [r["classifier_accuracy"]["per_finger_material"] for r in runs]
    fingers = ordered({f for t in tables for f in t}, FINGER_ORDER)
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
    """Write single_material_heatmap.png and single_material_bars.png; returns their paths."""
    fingers, materials, values = finger_material_table(runs)
    if not fingers or not materials:
        return []
    pooled = pooled_finger_material(runs, fingers, materials)
    heatmap = _heatmap_figure(runs, fingers, materials, values, pooled)
    bars = _bars_figure(runs, fingers, materials, with_counts=pooled is not None)
    return [
        _save(heatmap, out_dir / "single_material_heatmap.png", dpi),
        _save(bars, out_dir / "single_material_bars.png", dpi),
    ]


def _cell(value: float, extra: str = "") -> str:
    return "n/a" if np.isnan(value) else f"{value:.0f}%{extra}"


def _heatmap_figure(runs, fingers, materials, values, pooled) -> Figure:
    rows, cols = range(len(fingers)), range(len(materials))
    fig = Figure(figsize=(2.6 * len(materials) + 3.0, 0.9 * len(fingers) + 1.8))
    if pooled is None:  # runs written before counts existed: per-run accuracies only
        mean, _ = _mean_std(values)
        texts = [[_cell(mean[i, j]) for j in cols] for i in rows]
        title = f"Accuracy on judged touches, mean of {len(runs)} runs"
        image = _heatmap(fig.add_subplot(), mean, texts, fingers, materials, title)
    else:
        left, right = fig.subplots(1, 2)
        coverage = pooled["coverage"]
        texts = [
            [
                _cell(pooled["accuracy"][i, j])
                + ("" if np.isnan(coverage[i, j]) else f"\ncov {coverage[i, j]:.0f}%")
                + f"\nn={int(pooled['touches'][i, j])}"
                for j in cols
            ]
            for i in rows
        ]
        title = f"Accuracy on judged touches, coverage\n(touches of {len(runs)} runs pooled)"
        image = _heatmap(left, pooled["accuracy"], texts, fingers, materials, title)
        all_touch = pooled["accuracy_all_touches"]
        texts = [[_cell(all_touch[i, j]) for j in cols] for i in rows]
        title = "Accuracy over all touches\n(an abstention counts as not correct)"
        _heatmap(right, all_touch, texts, fingers, materials, title, ylabel=False)
    fig.colorbar(image, ax=fig.axes, label="[%]")
    return fig


def _bars_figure(runs, fingers, materials, with_counts: bool) -> Figure:
    panels = [("accuracy", "accuracy on judged touches [%]")]
    if with_counts:
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
            offset = x + (j - (len(materials) - 1) / 2) * width
            ax.bar(offset, np.nan_to_num(mean[:, j]), width, yerr=std[:, j], capsize=3,
                   color=colours[j], edgecolor="black", linewidth=0.5, label=material)  # fmt: skip
        ax.set_xticks(x, fingers)
        ax.set_ylim(0, 105)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_title("Classifier per sensor and material (mean ± std over runs)")
    axes[-1].legend(
        fontsize=8, ncol=len(materials), loc="upper center", bbox_to_anchor=(0.5, -0.15)
    )
    fig.tight_layout()
    return fig


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    with atomic_write(path, "wb") as f:
        fig.savefig(f, dpi=dpi, format=Path(path).suffix.lstrip(".") or "png")
    return path
