"""Pictures and the terminal summary of a finished mapping run, from its metrics.json data."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from neuralfeels_sem.viz.plots import (
    plot_fscore_curve,
    plot_matching_curve,
    plot_material_maps,
    plot_progression,
)
from neuralfeels_sem.viz.uncertainty_plots import plot_uncertainty_map

log = logging.getLogger(__name__)


def load_snapshots(directory: Path) -> list[tuple[float, dict]]:
    snapshots = []
    for path in sorted(directory.glob("*.npz")):
        with np.load(path) as data:
            maps = {k: data[k] for k in ("gt", "pred", "diff", "shade")}
            maps["matching_pct_image"] = float(data["matching_pct_image"])
            if "entropy" in data.files:  # snapshots written before uncertainty was recorded lack it
                maps["entropy"] = data["entropy"]
            snapshots.append((float(data["time_s"]), maps))
    return snapshots


def write_pictures(
    class_names: list[str], metrics: dict, snapshots_dir: Path, out: Path, dpi: int
) -> None:
    names = class_names
    if metrics["matching_curve"]:
        majority = metrics.get("baseline_majority") or {}
        plot_matching_curve(
            metrics["matching_curve"],
            out / "matching_curve.png",
            mean_class_curve=metrics.get("matching_mean_class_curve"),
            majority=majority,
            title=f"{partial_mark(metrics)}{metrics['config']['object']}: final mean-class "
            f"{_fmt(metrics.get('matching_mean_class_pct'), '.1f', '%')} "
            f"(majority map {_fmt(majority.get('matching_mean_class_pct'), '.1f', '%')})",
            dpi=dpi,
        )
    snapshots = load_snapshots(snapshots_dir)
    if snapshots:
        plot_material_maps(
            snapshots[-1][1], names, out / "material_maps.png", dpi=dpi, title=maps_title(metrics)
        )
        # At most 6 columns: evenly spaced over the run, always including the last one.
        pick = np.unique(
            np.linspace(0, len(snapshots) - 1, min(6, len(snapshots))).round().astype(int)
        )
        plot_progression(
            [snapshots[i] for i in pick],
            names,
            out / "progression.png",
            dpi=dpi,
            title=partial_mark(metrics).strip(),
        )
        if "entropy" in snapshots[-1][1]:
            plot_uncertainty_map(
                snapshots[-1][1],
                names,
                out / "uncertainty_map.png",
                dpi=dpi,
                title=uncertainty_title(metrics),
            )
    if metrics.get("fscore_curve"):
        plot_fscore_curve(metrics["fscore_curve"], out / "fscore_curve.png", dpi=dpi)


def partial_mark(metrics: dict) -> str:
    """The title prefix of a run stopped by a signal: its pictures show an unfinished map."""
    if not metrics.get("partial"):
        return ""
    return f"PARTIAL (interrupted after frame {metrics.get('frames_total', 0) - 1}) "


def _fmt(value, spec: str = ".1f", suffix: str = "") -> str:
    return "n/a" if value is None else f"{value:{spec}}{suffix}"


def maps_title(metrics: dict) -> str:
    """The final figures of material_maps.png, each beside the majority-material map's."""
    majority = metrics.get("baseline_majority") or {}
    return (
        f"{partial_mark(metrics)}{metrics['config']['object']}: mean-class {_fmt(metrics.get('matching_mean_class_pct'))}% "
        f"(majority map {_fmt(majority.get('matching_mean_class_pct'))}%), "
        f"matching {_fmt(metrics.get('matching_pct'))}% ({_fmt(majority.get('matching_pct'))}%)"
    )


def uncertainty_title(metrics: dict) -> str:
    """How well uncertainty predicts the final map's errors (the title of uncertainty_map.png)."""
    block = metrics.get("uncertainty") or {}
    return (
        f"{partial_mark(metrics)}{metrics['config']['object']}: uncertainty vs error "
        f"AUROC {_fmt(block.get('auroc'), '.2f')}, ECE {_fmt(block.get('ece'), '.3f')}"
    )


def _pct(value) -> str:
    return _fmt(value, ".1f", "%")


def _share(value) -> str:
    """A 0-1 share as a percentage."""
    return _fmt(None if value is None else 100.0 * value, ".1f", "%")


def summary_rows(metrics: dict) -> list[tuple[str, str, str, str]]:
    """(metric, run, majority-material map, untrained field) rows of the terminal summary."""
    acc = metrics["classifier_accuracy"]
    majority = metrics.get("baseline_majority") or {}
    base = metrics.get("baseline") or {}
    unc = metrics.get("uncertainty") or {}

    def matching(name: str, key: str) -> tuple[str, str, str, str]:
        return name, _pct(metrics.get(key)), _pct(majority.get(key)), _pct(base.get(key))

    return [
        matching("mean-class matching", "matching_mean_class_pct"),
        matching("matching (3D)", "matching_pct"),
        matching("mean IoU", "matching_miou_pct"),
        matching("matching on mesh", "matching_mesh_pct"),
        matching("matching (image)", "matching_pct_image"),
        (
            "F-score @5mm",
            _fmt(metrics.get("fscore_5mm"), ".3f"),
            "",
            _fmt(base.get("fscore_5mm"), ".3f"),
        ),
        (
            "Chamfer",
            _fmt(metrics.get("chamfer_mm"), ".2f", " mm"),
            "",
            _fmt(base.get("chamfer_mm"), ".2f", " mm"),
        ),
        (
            "uncertainty AUROC / ECE",
            f"{_fmt(unc.get('auroc'), '.2f')} / {_fmt(unc.get('ece'), '.3f')}",
            "",
            "",
        ),
        ("classifier accuracy (judged)", _share(acc.get("overall")), "", ""),
        ("classifier coverage", _share(acc.get("coverage")), "", ""),
        ("classifier acc. (all touches)", _share(acc.get("accuracy_all_touches")), "", ""),
        ("frames / wall time", f"{metrics['frames']} / {metrics['wall_s']:.0f} s", "", ""),
        ("realtime factor", _fmt(metrics.get("realtime_factor"), ".2f"), "", ""),
        ("busy: producer / mapper", _busy(metrics), "", ""),
        ("producer: acquire/classify/perceive", _stages(metrics), "", ""),
    ] + _pace_rows(metrics)


def _pace_rows(metrics: dict) -> list[tuple[str, str, str, str]]:
    """At sensor.pace=realtime: the frames not mapped (those whose touches were fused
    among them) and the largest lag; nothing offline."""
    if metrics.get("pace") != "realtime":
        return []
    dropped = f"{metrics.get('frames_dropped', 0)} / {metrics.get('touch_frames', 0)}"
    return [
        ("frames dropped / touches kept", dropped, "", ""),
        ("largest lag", _fmt(metrics.get("lag_max_s"), ".2f", " s"), "", ""),
    ]


def busy_share(metrics: dict, key: str) -> float | None:
    """A thread's CPU time (`producer_cpu_s` or `mapper_cpu_s`) as a share of the loop's
    wall time: the thread near 1 bounds the realtime factor. None for a run without it."""
    cpu_s, wall_s = metrics.get(key), metrics.get("wall_s") or 0.0
    return None if cpu_s is None or wall_s <= 0 else cpu_s / wall_s


def _busy(metrics: dict) -> str:
    producer, mapper = (busy_share(metrics, k) for k in ("producer_cpu_s", "mapper_cpu_s"))
    if producer is None or mapper is None:
        return "n/a"
    return f"{_share(producer)} / {_share(mapper)}"


def stage_shares(metrics: dict) -> dict[str, float]:
    """The producer's CPU time by stage (`producer_stage_cpu_s`: acquire, classify,
    perceive) as shares of the loop's wall time; empty for a run without it."""
    stages, wall_s = metrics.get("producer_stage_cpu_s") or {}, metrics.get("wall_s") or 0.0
    return {stage: cpu_s / wall_s for stage, cpu_s in stages.items()} if wall_s > 0 else {}


def _stages(metrics: dict) -> str:
    shares = stage_shares(metrics)
    if not shares:
        return "n/a"
    # the sensor's own process (mapping.acquire_process) counts with the acquisition
    acquire = shares.get("acquire", 0.0) + shares.get("acquire_process", 0.0)
    parts = (acquire, shares.get("classify", 0.0), shares.get("perceive", 0.0))
    return "/".join(f"{100 * share:.0f}%" for share in parts)


def print_summary(metrics: dict, out: Path) -> None:
    rows = summary_rows(metrics)
    width = max(len(r[0]) for r in rows)
    lines = [f"{'metric':<{width}}  {'run':>14}  {'majority':>9}  {'untrained':>10}"]
    lines += [f"{r[0]:<{width}}  {r[1]:>14}  {r[2]:>9}  {r[3]:>10}" for r in rows]
    material = (metrics.get("baseline_majority") or {}).get("material")
    if material:
        lines.append(
            f"majority = the whole object painted {material}, the ground truth's largest material"
        )
    if metrics.get("oracles"):
        lines.append(f"simulator oracles used: {', '.join(metrics['oracles'])}")
    for note in metrics.get("notes") or []:
        lines.append(f"note: {note}")
    print("\n".join(lines))
    print(f"run directory: {out}")
