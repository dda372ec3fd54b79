"""Evaluation on real scanned YCB meshes (irregular triangles, thin parts); skips without ../shared/data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from neuralfeels_sem.core.geometry import Intrinsics, backproject, transform_points
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.eval.image_matching import ImageMatcher
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.shape import shape_metrics
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject


def load_ycb(shared_data: Path, name: str) -> trimesh.Trimesh:
    mesh = trimesh.load(shared_data / "ycb" / name / "model.obj", force="mesh")
    mesh.merge_vertices()
    mesh.apply_translation(-mesh.bounds.mean(axis=0))
    return mesh


def test_power_drill_label_maps(shared_data: Path) -> None:
    mesh = load_ycb(shared_data, "PowerDrill")
    centre = mesh.triangles_center
    labels = np.where(centre[:, 2] > 0, 0, 3)  # plastic top, wood bottom
    labels[np.abs(centre[:, 2]) < 0.005] = IGNORE
    obj = MaterialObject("power_drill", mesh, labels, tuple(DEFAULT_MATERIALS))
    matcher = ImageMatcher(obj, views=3, size=128)
    maps = matcher.maps(lambda x: np.where(x[:, 2] > 0, 0, 3))
    # Rendered depth lies on the scanned surface.
    k = Intrinsics(**maps["intrinsics"])
    for v in range(3):
        points = transform_points(maps["poses"][v], backproject(matcher.depth[v], k))
        _, distance, _ = trimesh.proximity.closest_point(mesh, points[::25])
        assert np.median(distance) < 5e-4 and np.quantile(distance, 0.99) < 1e-3
    # The height rule is exact up to faces straddling the ignore band's edges.
    assert maps["matching_pct_image"] > 99.0
    assert MatchingEvaluator(obj, 20000).score(lambda x: np.where(x[:, 2] > 0, 0, 3)) > 99.0


def test_scan_against_a_shifted_copy(shared_data: Path) -> None:
    mesh = load_ycb(shared_data, "MustardBottle")
    shifted = mesh.copy()
    shifted.apply_translation([0.002, 0.0, 0.0])
    result = shape_metrics(shifted, mesh, num_samples=20000)
    assert result["fscore_5mm"] > 0.98
    assert 0.3 < result["chamfer_mm"] < 2.0  # at most the 2 mm shift, less on faces parallel to it
    curve = dict(result["fscore_curve"])
    assert curve[1.0] < curve[5.0] <= curve[20.0] == 1.0
