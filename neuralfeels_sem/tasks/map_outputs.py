"""Pictures and the terminal summary of a finished mapping run."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from neuralfeels_sem.tasks.map_metrics import RunScorer
from neuralfeels_sem.viz.plots import (
    plot_fscore_curve,
    plot_matching_curve,
    plot_material_maps,
    plot_progression,
)

log = logging.getLogger(__name__)


def load_snapshots(directory: Path) -> list[tuple[float, dict]]:
    snapshots = []
    for path in sorted(directory.glob("*.npz")):
        with np.load(path) as data:
            maps = {k: data[k] for k in ("gt", "pred", "diff", "shade")}
            maps["matching_pct_image"] = float(data["matching_pct_image"])
            snapshots.append((float(data["time_s"]), maps))
    return snapshots


def write_pictures(
    scorer: RunScorer, metrics: dict, snapshots_dir: Path, out: Path, dpi: int
) -> None:
    names = scorer.class_names
    if metrics["matching_curve"]:
        plot_matching_curve(
            metrics["matching_curve"],
            out / "matching_curve.png",
            baseline=metrics["baseline"].get("matching_pct"),
            title=f"{metrics['config']['object']}: final {metrics['matching_pct']:.1f}%",
            dpi=dpi,
        )
    snapshots = load_snapshots(snapshots_dir)
    if snapshots:
        plot_material_maps(snapshots[-1][1], names, out / "material_maps.png", dpi=dpi)
        # At most 6 columns: evenly spaced over the run, always including the last one.
        pick = np.unique(
            np.linspace(0, len(snapshots) - 1, min(6, len(snapshots))).round().astype(int)
        )
        plot_progression([snapshots[i] for i in pick], names, out / "progression.png", dpi=dpi)
    if metrics.get("fscore_curve"):
        plot_fscore_curve(metrics["fscore_curve"], out / "fscore_curve.png", dpi=dpi)


def _fmt(value, spec: str = ".1f", suffix: str = "") -> str:
    return "n/a" if value is None else f"{value:{spec}}{suffix}"


def print_summary(metrics: dict, out: Path) -> None:
    acc = metrics["classifier_accuracy"]
    base = metrics["baseline"]
    rows = [
        (
            "matching (3D)",
            _fmt(metrics["matching_pct"], ".1f", "%"),
            _fmt(base.get("matching_pct"), ".1f", "%"),
        ),
        (
            "matching (image)",
            _fmt(metrics["matching_pct_image"], ".1f", "%"),
            _fmt(base.get("matching_pct_image"), ".1f", "%"),
        ),
        ("F-score @5mm", _fmt(metrics["fscore_5mm"], ".3f"), _fmt(base.get("fscore_5mm"), ".3f")),
        (
            "Chamfer",
            _fmt(metrics["chamfer_mm"], ".2f", " mm"),
            _fmt(base.get("chamfer_mm"), ".2f", " mm"),
        ),
        (
            "classifier accuracy",
            _fmt(None if acc["overall"] is None else 100 * acc["overall"], ".1f", "%"),
            "",
        ),
        ("frames / wall time", f"{metrics['frames']} / {metrics['wall_s']:.0f} s", ""),
        ("realtime factor", _fmt(metrics["realtime_factor"], ".2f"), ""),
    ]
    width = max(len(r[0]) for r in rows)
    lines = [f"{'metric':<{width}}  {'run':>14}  {'untrained':>10}"]
    lines += [f"{name:<{width}}  {value:>14}  {floor:>10}" for name, value, floor in rows]
    print("\n".join(lines))
    print(f"run directory: {out}")
