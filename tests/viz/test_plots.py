"""Run pictures: valid, non-empty PNGs with the expected content; the coloured mesh round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.core.palette import MATERIAL_COLOURS
from neuralfeels_sem.viz.material_mesh import color_mesh, save_material_mesh
from neuralfeels_sem.viz.plots import (
    MISMATCH_COLOUR,
    diff_image,
    label_image,
    plot_fscore_curve,
    plot_matching_curve,
    plot_matching_curves,
    plot_material_maps,
    plot_progression,
)
from tests.viz.images import assert_png

CLASSES = list(DEFAULT_MATERIALS)


def synthetic_maps(views: int = 2, size: int = 48, wrong_cols: int = 10) -> dict:
    """A disc: left half plastic, right half fabric, a band of ignore; prediction wrong on some columns."""
    v, u = np.mgrid[:size, :size]
    disc = (u - size / 2) ** 2 + (v - size / 2) ** 2 < (0.4 * size) ** 2
    gt = np.full((views, size, size), -2)
    gt[:, disc] = np.where(u[disc] < size / 2, 0, 2)
    gt[:, disc & (v < size / 4)] = -1
    pred = np.where(gt == -1, 0, gt)
    pred[:, :, :wrong_cols] = np.where(pred[:, :, :wrong_cols] >= 0, 3, pred[:, :, :wrong_cols])
    diff = (gt >= 0) & (pred != gt)
    roi = gt >= 0
    return {
        "gt": gt,
        "pred": pred,
        "diff": diff,
        "shade": np.full(gt.shape, 0.9, dtype=np.float32),
        "matching_pct_image": float(100 * (1 - diff.sum() / roi.sum())),
    }


def test_matching_curve_png(tmp_path: Path) -> None:
    curve = [[0, 0.0, 40.0], [5, 0.5, 55.0], [10, 1.0, 71.5]]
    path = plot_matching_curve(
        curve, tmp_path / "matching_curve.png", baseline=38.0, title="plushie"
    )
    assert_png(path)


def test_matching_curves_png_and_empty_run(tmp_path: Path) -> None:
    curves = {
        "run 0": [[0, 0.0, 40.0], [5, 0.5, 60.0]],
        "run 1": [[0, 0.0, 45.0], [5, 0.5, 80.0]],
        "empty": [],
    }
    assert_png(plot_matching_curves(curves, tmp_path / "curves.png"))


def test_matching_curve_rejects_bad_rows(tmp_path: Path) -> None:
    with pytest.raises(ValueError):
        plot_matching_curve([[0, 1.0]], tmp_path / "bad.png")


def test_label_and_diff_images_have_exact_colours() -> None:
    maps = synthetic_maps(views=1)
    gt, diff = maps["gt"][0], maps["diff"][0]
    image = label_image(gt, CLASSES)
    assert tuple(image[gt == 0][0]) == MATERIAL_COLOURS["plastic"]
    assert tuple(image[gt == -1][0]) == (0, 0, 0)
    shaded = label_image(gt, CLASSES, np.full(gt.shape, 0.5))
    assert shaded[gt == 0][0][0] == MATERIAL_COLOURS["plastic"][0] // 2
    assert tuple(shaded[gt == -1][0]) == (0, 0, 0) and tuple(shaded[0, 0]) == (255, 255, 255)
    d = diff_image(gt, diff)
    assert (d[diff] == MISMATCH_COLOUR).all()
    assert (d[(gt >= 0) & ~diff] != MISMATCH_COLOUR).any(axis=-1).all()


def test_material_maps_png(tmp_path: Path) -> None:
    pixels = assert_png(
        plot_material_maps(synthetic_maps(views=3), CLASSES, tmp_path / "material_maps.png")
    )
    assert pixels.shape[0] > pixels.shape[1]  # three rows of views, taller than wide
    # The mismatch colour appears in the difference column.
    assert (np.abs(pixels.astype(int) - MISMATCH_COLOUR).sum(axis=-1) < 10).any()


def test_material_maps_need_all_keys(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="diff"):
        plot_material_maps(
            {"gt": np.zeros((1, 4, 4)), "pred": np.zeros((1, 4, 4))}, CLASSES, tmp_path / "x.png"
        )


def test_progression_png(tmp_path: Path) -> None:
    snapshots = [
        (t, synthetic_maps(views=1, wrong_cols=w)) for t, w in ((0.0, 40), (1.0, 20), (2.0, 5))
    ]
    pixels = assert_png(plot_progression(snapshots, CLASSES, tmp_path / "progression.png"))
    assert pixels.shape[1] > 2 * pixels.shape[0]  # one row: snapshots then ground truth
    with pytest.raises(ValueError):
        plot_progression([], CLASSES, tmp_path / "none.png")
    # A partial run's mark is drawn above the row (same size, other pixels).
    marked = plot_progression(
        snapshots, CLASSES, tmp_path / "partial.png", title="PARTIAL (interrupted after frame 7)"
    )
    marked_pixels = assert_png(marked)
    assert marked_pixels.shape == pixels.shape and not np.array_equal(marked_pixels, pixels)


def test_fscore_curve_png(tmp_path: Path) -> None:
    curve = [[float(t), min(1.0, t / 8)] for t in range(1, 21)]
    assert_png(plot_fscore_curve(curve, tmp_path / "fscore.png"))


def test_material_mesh_ply_round_trip(tmp_path: Path) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    path = save_material_mesh(
        mesh, lambda x: np.where(x[:, 2] > 0, 1, 3), CLASSES, tmp_path / "material_mesh.ply"
    )
    loaded = trimesh.load(path, process=False)
    assert len(loaded.vertices) == len(mesh.vertices)
    colours = np.asarray(loaded.visual.vertex_colors)[:, :3]
    top = mesh.vertices[:, 2] > 0
    assert (colours[top] == MATERIAL_COLOURS["metal"]).all()
    assert (colours[~top] == MATERIAL_COLOURS["wood"]).all()


def test_color_mesh_checks_label_count() -> None:
    mesh = trimesh.creation.box()
    with pytest.raises(ValueError, match="labels for"):
        color_mesh(mesh, np.zeros(3, dtype=int), CLASSES)
