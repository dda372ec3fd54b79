"""`pose_curves.png` of a sweep: every tracked run's pose error over time.

One panel per object, one colour per setting (what the sweep varied besides the object
and the seed), each run's `pose_error_curve` (metrics.json, [frame, time_s, error_mm])
drawn thin, with the setting's mean error over its runs in the legend. Runs with the
ground-truth pose have no curve and are left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure


def _setting(job: dict, varying: list[str]) -> str:
    overrides = job.get("overrides", {})
    keys = [k for k in varying if k not in ("object", "seed") and k in overrides]
    return ", ".join(f"{k.split('.')[-1]}={overrides[k]}" for k in keys) or "tracked"


def plot_pose_curves(
    runs: list[tuple[dict, dict]], varying: list[str], path: Path, dpi: int = 120
) -> Path | None:
    """runs: (job, metrics) pairs; draws those with a pose error curve (None: no such run)."""
    tracked = [(j, m) for j, m in runs if m.get("pose_error_curve")]
    if not tracked:
        return None
    objects = sorted({str(m.get("config", {}).get("object", "?")) for _, m in tracked})
    settings = sorted({_setting(j, varying) for j, _ in tracked})
    fig = Figure(figsize=(4.8 * len(objects), 3.6), layout="constrained")
    axes = fig.subplots(1, len(objects), squeeze=False)[0]
    for ax, name in zip(axes, objects):
        for k, setting in enumerate(settings):
            members = [
                m
                for j, m in tracked
                if str(m.get("config", {}).get("object", "?")) == name
                and _setting(j, varying) == setting
            ]
            if not members:
                continue
            means = [float(m["pose_error_mm"]) for m in members]
            for i, metrics in enumerate(members):
                curve = np.asarray(metrics["pose_error_curve"], dtype=np.float64).reshape(-1, 3)
                label = f"{setting}: mean {np.mean(means):.2f} mm (n={len(members)})"
                ax.plot(curve[:, 1], curve[:, 2], color=f"C{k % 10}", lw=1.0, alpha=0.8,
                        label=label if i == 0 else None)  # fmt: skip
        ax.set_title(name)
        ax.set_xlabel("sensor time [s]")
        ax.set_ylabel("average 3D pose error [mm]")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.savefig(path, dpi=dpi)
    return path
