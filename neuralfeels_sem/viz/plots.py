"""Figures of one run: matching curve, material maps (fig. 5B), progression (fig. 5C), F-score curve.

Uses matplotlib's object API (no pyplot state), so it is safe in sweeps and headless.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from neuralfeels_sem.core.palette import BACKGROUND_COLOUR, IGNORE_COLOUR, class_colours, colorize
from neuralfeels_sem.utils.atomic import atomic_write

MATCH_COLOUR = (225, 225, 225)  # inside the regions of interest, prediction agrees
MISMATCH_COLOUR = (230, 0, 120)  # inside the regions of interest, prediction differs


def _save(fig: Figure, path: Path | str, dpi: int) -> Path:
    path = Path(path)
    with atomic_write(path, "wb") as f:  # a killed run leaves the old picture or the new one
        fig.savefig(f, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    return path


def _check_curve(curve: Sequence[Sequence[float]], name: str = "curve") -> np.ndarray:
    array = np.asarray(curve, dtype=np.float64).reshape(-1, 3) if len(curve) else np.zeros((0, 3))
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must be a list of [frame_index, time_s, matching_pct]")
    return array


def plot_matching_curve(
    curve: Sequence[Sequence[float]],
    path: Path | str,
    baseline: float | None = None,
    title: str = "",
    dpi: int = 120,
    mean_class_curve: Sequence[Sequence[float]] | None = None,
    majority: Mapping[str, float] | None = None,
) -> Path:
    """One run's matching over sensor time (figure 5A), read against the majority-material map.

    `curve` is plain matching, `mean_class_curve` the mean-class form (drawn first when
    given); `majority` the constant majority map's figures (dashed, same colours);
    `baseline` the untrained field's plain matching (grey, dashed).
    """
    curves = {"matching": curve}
    if mean_class_curve:
        curves = {"mean-class matching": mean_class_curve, "matching": curve}
    floors = {}
    if majority:
        for name, key in (("mean-class", "matching_mean_class_pct"), ("matching", "matching_pct")):
            if name == "mean-class" and not mean_class_curve:
                continue
            if majority.get(key) is not None:
                floors[f"majority map, {name}"] = float(majority[key])
    return plot_matching_curves(
        curves, path, baseline=baseline, title=title, dpi=dpi, legend=True, floors=floors
    )


def plot_matching_curves(
    curves: Mapping[str, Sequence[Sequence[float]]],
    path: Path | str,
    baseline: float | None = None,
    title: str = "",
    dpi: int = 120,
    legend: bool = True,
    floors: Mapping[str, float] | None = None,
) -> Path:
    """Several matching curves on one axis (figure 5A); `floors` are dashed horizontal
    lines in the colour of the curve at the same position (e.g. the majority map's figures)."""
    fig = Figure(figsize=(6.0, 3.8))
    ax = fig.add_subplot()
    for k, (name, value) in enumerate((floors or {}).items()):
        ax.axhline(
            value, color=f"C{k}", linestyle="--", linewidth=1, label=f"{name} ({value:.1f}%)"
        )
    for name, curve in curves.items():
        array = _check_curve(curve, f"matching curve {name!r}")
        if len(array):
            final = array[-1, 2]
            ax.plot(
                array[:, 1],
                array[:, 2],
                marker="o",
                markersize=3,
                label=f"{name} (final {final:.1f}%)",
            )
    if baseline is not None:
        ax.axhline(
            baseline,
            color="grey",
            linestyle="--",
            linewidth=1,
            label=f"untrained field ({baseline:.1f}%)",
        )
    ax.set_xlabel("sensor time [s]")
    ax.set_ylabel("matching [%]")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.set_title(title or "Matching percentage over time")
    if legend or baseline is not None:
        ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return _save(fig, path, dpi)


def _shaded(rgb: np.ndarray, shade: np.ndarray | None, mask: np.ndarray) -> np.ndarray:
    if shade is None:
        return rgb
    out = rgb.astype(np.float32)
    out[mask] *= shade[mask][:, None]
    return out.clip(0, 255).astype(np.uint8)


def label_image(
    labels: np.ndarray, class_names: Sequence[str], shade: np.ndarray | None = None
) -> np.ndarray:
    """(H, W) labels -> (H, W, 3) uint8, materials shaded by `shade`, ignore black, background white."""
    return _shaded(colorize(labels, class_names), shade, labels >= 0)


def diff_image(gt: np.ndarray, diff: np.ndarray) -> np.ndarray:
    """The difference mask: mismatches magenta, matches light grey, outside the ROI black."""
    out = np.empty((*gt.shape, 3), dtype=np.uint8)
    out[:] = BACKGROUND_COLOUR
    out[gt == -1] = IGNORE_COLOUR
    out[gt >= 0] = MATCH_COLOUR
    out[diff] = MISMATCH_COLOUR
    return out


def _legend_handles(
    class_names: Sequence[str], with_diff: bool, used: np.ndarray | None = None
) -> list[Patch]:
    """Legend of the classes in `used` (all when None), the not-scored colour and the mismatch colour."""
    colours = class_colours(class_names) / 255.0
    shown = (
        set(range(len(class_names)))
        if used is None
        else {int(u) for u in np.unique(used) if u >= 0}
    )
    handles = [Patch(color=colours[i], label=n) for i, n in enumerate(class_names) if i in shown]
    handles.append(Patch(color=np.array(IGNORE_COLOUR) / 255.0, label="not scored"))
    if with_diff:
        handles.append(Patch(color=np.array(MISMATCH_COLOUR) / 255.0, label="mismatch"))
    return handles


def _check_maps(maps: Mapping) -> None:
    for key in ("gt", "pred", "diff"):
        if key not in maps:
            raise ValueError(
                f"maps lacks {key!r}; pass the dict from render_label_maps / ImageMatcher.maps"
            )
    if not (maps["gt"].shape == maps["pred"].shape == maps["diff"].shape) or maps["gt"].ndim != 3:
        raise ValueError(f"gt, pred, diff must share a (V, H, W) shape, got {maps['gt'].shape}")


def plot_material_maps(
    maps: Mapping,
    class_names: Sequence[str],
    path: Path | str,
    dpi: int = 120,
    title: str | None = None,
) -> Path:
    """Rows = views; columns = ground truth | prediction | difference (figure 5B).

    `title` replaces the default one (the image-form matching of all views)."""
    _check_maps(maps)
    views = maps["gt"].shape[0]
    shade = maps.get("shade")
    fig = Figure(figsize=(7.5, 2.4 * views + 0.8), layout="constrained")
    axes = fig.subplots(views, 3, squeeze=False)
    for v in range(views):
        s = None if shade is None else shade[v]
        panels = (
            label_image(maps["gt"][v], class_names, s),
            label_image(maps["pred"][v], class_names, s),
            diff_image(maps["gt"][v], maps["diff"][v]),
        )
        for c, image in enumerate(panels):
            axes[v, c].imshow(image, interpolation="nearest")
            axes[v, c].set_xticks([])
            axes[v, c].set_yticks([])
        roi = maps["gt"][v] >= 0
        pct = 100.0 * (1 - maps["diff"][v].sum() / roi.sum()) if roi.any() else float("nan")
        axes[v, 0].set_ylabel(f"view {v}", fontsize=9)
        axes[v, 2].set_xlabel(f"{pct:.1f}% matching", fontsize=9)
    for c, name in enumerate(("ground truth", "prediction", "difference")):
        axes[0, c].set_title(name, fontsize=10)
    overall = maps.get("matching_pct_image")
    if title is None and overall is not None:
        title = f"Material maps: {overall:.1f}% matching in the regions of interest"
    if title:
        fig.suptitle(title, fontsize=11)
    used = np.concatenate([maps["gt"].reshape(-1), maps["pred"].reshape(-1)])
    fig.legend(
        handles=_legend_handles(class_names, True, used),
        loc="outside lower center",
        ncol=min(7, len(class_names) + 2),
        fontsize=8,
    )
    return _save(fig, path, dpi)


def plot_progression(
    snapshots: Sequence[tuple[float, Mapping]],
    class_names: Sequence[str],
    path: Path | str,
    view: int = 0,
    dpi: int = 120,
    title: str = "",
) -> Path:
    """The predicted map from one view at several times, then the ground truth (figure 5C);
    `title` above them all (a partial run's mark)."""
    if not snapshots:
        raise ValueError("plot_progression needs at least one (time_s, maps) snapshot")
    for _, maps in snapshots:
        _check_maps(maps)
    columns = len(snapshots) + 1
    fig = Figure(figsize=(2.2 * columns, 3.0), layout="constrained")
    axes = fig.subplots(1, columns, squeeze=False)[0]
    for ax, (time_s, maps) in zip(axes, snapshots):
        s = None if maps.get("shade") is None else maps["shade"][view]
        ax.imshow(label_image(maps["pred"][view], class_names, s), interpolation="nearest")
        pct = maps.get("matching_pct_image")
        ax.set_title(
            f"t = {time_s:.1f} s" + (f"\n{pct:.1f}%" if pct is not None else ""), fontsize=9
        )
    last = snapshots[-1][1]
    shown = [m["pred"][view].reshape(-1) for _, m in snapshots] + [last["gt"][view].reshape(-1)]
    s = None if last.get("shade") is None else last["shade"][view]
    axes[-1].imshow(label_image(last["gt"][view], class_names, s), interpolation="nearest")
    axes[-1].set_title("ground truth", fontsize=9)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    if title:
        fig.suptitle(title, fontsize=10)
    fig.legend(
        handles=_legend_handles(class_names, False, np.concatenate(shown)),
        loc="outside lower center",
        ncol=len(class_names) + 1,
        fontsize=8,
    )
    return _save(fig, path, dpi)


def plot_fscore_curve(
    curve: Sequence[Sequence[float]], path: Path | str, title: str = "", dpi: int = 120
) -> Path:
    """F-score against distance threshold ([[t_mm, f], ...] from shape_metrics)."""
    array = np.asarray(curve, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2 or not len(array):
        raise ValueError("fscore curve must be a non-empty list of [threshold_mm, fscore]")
    fig = Figure(figsize=(5.0, 3.5))
    ax = fig.add_subplot()
    ax.plot(array[:, 0], array[:, 1], marker="o", markersize=3)
    ax.set_xlabel("threshold [mm]")
    ax.set_ylabel("F-score")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.set_title(title or "Shape F-score against the ground-truth mesh")
    fig.tight_layout()
    return _save(fig, path, dpi)
