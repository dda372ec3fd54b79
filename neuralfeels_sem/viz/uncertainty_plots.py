"""uncertainty_map.png: the views of material_maps.png, coloured by the map's uncertainty.

Columns: prediction | uncertainty (normalised entropy, 0-1, one colour scale for every
view) | difference, so high uncertainty can be read against where the map is wrong.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from neuralfeels_sem.viz.plots import _save, diff_image, label_image

UNCERTAINTY_CMAP = "magma"
OFF_OBJECT_COLOUR = "white"


def plot_uncertainty_map(
    maps: Mapping,
    class_names: Sequence[str],
    path: Path | str,
    dpi: int = 120,
    title: str | None = None,
) -> Path:
    """Rows = views; `maps` holds gt, pred, diff and entropy (V, H, W), as a progression snapshot."""
    for key in ("gt", "pred", "diff", "entropy"):
        if key not in maps:
            raise ValueError(f"maps lacks {key!r}; pass a snapshot taken by RunScorer.snapshot")
    if maps["entropy"].shape != maps["gt"].shape or maps["gt"].ndim != 3:
        raise ValueError(
            f"entropy {maps['entropy'].shape} and gt {maps['gt'].shape} must share a (V, H, W) shape"
        )
    views = maps["gt"].shape[0]
    shade = maps.get("shade")
    fig = Figure(figsize=(7.5, 2.4 * views + 0.8), layout="constrained")
    axes = fig.subplots(views, 3, squeeze=False)
    # Background and pixels with no value are drawn white.
    cmap = colormaps[UNCERTAINTY_CMAP].with_extremes(bad=OFF_OBJECT_COLOUR)
    for v in range(views):
        s = None if shade is None else shade[v]
        axes[v, 0].imshow(label_image(maps["pred"][v], class_names, s), interpolation="nearest")
        shown = axes[v, 1].imshow(
            np.ma.masked_invalid(maps["entropy"][v]), cmap=cmap, vmin=0, vmax=1
        )
        axes[v, 2].imshow(diff_image(maps["gt"][v], maps["diff"][v]), interpolation="nearest")
        for ax in axes[v]:
            ax.set_xticks([])
            ax.set_yticks([])
        axes[v, 0].set_ylabel(f"view {v}", fontsize=9)
        seen = np.isfinite(maps["entropy"][v])
        mean = float(np.mean(maps["entropy"][v][seen])) if seen.any() else float("nan")
        axes[v, 1].set_xlabel(f"mean {mean:.2f}", fontsize=9)
    for c, name in enumerate(("prediction", "uncertainty (entropy)", "difference")):
        axes[0, c].set_title(name, fontsize=10)
    fig.colorbar(shown, ax=axes[:, 1].tolist(), location="bottom", shrink=0.8, label="H / log C")
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, path, dpi)
