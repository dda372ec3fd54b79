"""touch_suggestions.png: the map's surface samples coloured by touch score, the suggestions on top.

Three orthographic views of the object frame (x-y, x-z, y-z): samples coloured by score
(0-1, one scale), the touches counted for novelty as black dots, the suggested points as numbered stars
(1 = touch first), the order of touch_suggestions.json.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from neuralfeels_sem.viz.plots import _save

VIEWS = (("x", "y", 0, 1), ("x", "z", 0, 2), ("y", "z", 1, 2))


def draw_suggestions(advice, points: np.ndarray, path: Path | str, dpi: int = 100) -> Path:
    """Draw `advice` (a TouchAdvice) and its suggested `points` (k, 3) into `path`."""
    scores = advice.score(advice.surface) if len(advice.surface) else np.zeros(0)
    fig = Figure(figsize=(10.5, 3.8), layout="constrained")
    axes = fig.subplots(1, 3)
    shown = None
    for ax, (a, b, i, j) in zip(axes, VIEWS):
        if len(advice.surface):
            shown = ax.scatter(
                advice.surface[:, i],
                advice.surface[:, j],
                c=scores,
                s=4,
                cmap="viridis",
                vmin=0.0,
                vmax=1.0,
            )
        if len(advice.touched):
            ax.scatter(advice.touched[:, i], advice.touched[:, j], c="black", s=3)
        ax.scatter(points[:, i], points[:, j], marker="*", s=140, c="red", edgecolors="white")
        for n, p in enumerate(points, start=1):
            ax.annotate(str(n), (p[i], p[j]), xytext=(4, 4), textcoords="offset points")
        ax.set_xlabel(f"{a} (m)")
        ax.set_ylabel(f"{b} (m)")
        ax.set_aspect("equal", adjustable="datalim")
    if shown is not None:
        fig.colorbar(shown, ax=axes, label="touch score (uncertainty + novelty)", shrink=0.8)
    fig.suptitle(
        f"where to touch next after frame {advice.frame_index}: "
        f"{len(points)} suggestions, {len(advice.touched)} touches (black)"
    )
    return _save(fig, Path(path), dpi)
