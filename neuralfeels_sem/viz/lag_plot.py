"""bench.map_lag's picture: per run, the field's mean-class curve beside the nearest-point
maps of the readings the vote keeps, of all readings and of the presses' true materials,
over sensor time."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

from neuralfeels_sem.viz.plots import _save

SERIES_STYLE = {  # bench.map_lag's series: colour, line, legend
    "field": ("C0", "-", "field (the map)"),
    "kept": ("C3", "-.", "readings the vote keeps"),
    "readings": ("C1", "--", "all readings"),
    "placement": ("C2", ":", "presses read right (oracle)"),
}


def plot_map_lag(
    records: Sequence[dict], path: Path | str, columns: int = 4, dpi: int = 100
) -> Path:
    """One panel per map_lag record (its `rows`, `level`, object, seed and policy)."""
    if not records:
        raise ValueError("plot_map_lag needs at least one record")
    cols = min(columns, len(records))
    rows = math.ceil(len(records) / cols)
    fig = Figure(figsize=(3.2 * cols, 2.4 * rows))
    axes = fig.subplots(rows, cols, squeeze=False, sharey=True)
    for ax, record in zip(axes.flat, records):
        times = [r["time_s"] for r in record["rows"]]
        for key, (colour, line, label) in SERIES_STYLE.items():
            values = [math.nan if r[key] is None else r[key] for r in record["rows"]]
            ax.plot(times, values, color=colour, linestyle=line, linewidth=1.2, label=label)
        ax.axhline(record["level"], color="grey", linewidth=0.8)
        ax.set_title(f"{record['object']} s{record['seed']} {record['policy']}", fontsize=8)
        ax.set_ylim(0, 100)
        ax.set_xlabel("sensor time (s)", fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(records) :]:
        ax.axis("off")
    axes[0, 0].set_ylabel("mean-class matching (%)", fontsize=7)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=7, frameon=False)
    legend_in = 0.45  # two rows of legend under the panels, whatever the figure's height
    fig.tight_layout(rect=(0, legend_in / fig.get_figheight(), 1, 1))
    return _save(fig, path, dpi)
