"""maps_grid.png: every sweep job's final material map (its material_maps.png) in one picture.

Each tile is a job's ground truth | prediction | difference, titled with the job's setting
(the overrides the sweep varies) and its mean-class matching beside the majority-material
map's, so a benchmark of many objects (experiment=unseen_objects) is read at a glance.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

import matplotlib.image as mpimg
from matplotlib.figure import Figure

MAPS_FILE = "material_maps.png"
# material_maps.png is taller than wide (fixed views in rows, three columns): five tiles a
# row keep the 20 objects of experiment=unseen_objects on one readable page.
TILE_WIDTH_IN = 4.0
TITLE_CHARS = 56  # a title line at 9 pt across one tile; longer titles wrap (two lines fit)


@dataclass(frozen=True)
class MapTile:
    picture: Path  # a job's material_maps.png
    title: str


def tile_title(setting: str, metrics: dict) -> str:
    """`setting` and its final mean-class matching beside the majority map's, where known."""
    score = metrics.get("matching_mean_class_pct")
    floor = (metrics.get("baseline_majority") or {}).get("matching_mean_class_pct")
    if not isinstance(score, int | float):
        return setting
    text = f"{setting}: mean-class {score:.1f}%"
    if isinstance(floor, int | float):
        text += f" (majority {floor:.1f}%)"
    return text


def plot_maps_grid(tiles: list[MapTile], path: Path, columns: int = 5, dpi: int = 120) -> Path:
    """Tile the pictures `columns` wide, in the given order; returns `path`."""
    if not tiles:
        raise ValueError("plot_maps_grid: no material maps to tile")
    if columns < 1:
        raise ValueError(f"plot_maps_grid: columns={columns} must be >= 1")
    images = [mpimg.imread(tile.picture) for tile in tiles]
    aspect = max(image.shape[0] / image.shape[1] for image in images)
    columns = min(columns, len(tiles))
    rows = math.ceil(len(tiles) / columns)
    tile_height = TILE_WIDTH_IN * aspect + 0.55  # room for a two-line title
    fig = Figure(figsize=(TILE_WIDTH_IN * columns, tile_height * rows), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    for ax, tile, image in zip(axes, tiles, images):
        ax.imshow(image)
        ax.set_title(textwrap.fill(tile.title, TITLE_CHARS), fontsize=9)
    for ax in axes:
        ax.set_axis_off()
    fig.suptitle(f"Final material maps ({len(tiles)} runs): ground truth | prediction | difference")
    fig.savefig(path, dpi=dpi)
    return path
