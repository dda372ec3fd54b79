"""The surface curvature at a press (sim/surface_curvature.py) and its bins in the
classifier's reports (evaluate.curvature_bin, dataset.curvature_bins)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.perception.classifier.dataset import curvature_bins
from neuralfeels_sem.perception.classifier.evaluate import curvature_bin
from neuralfeels_sem.sim.surface_curvature import SurfaceCurvature


@pytest.mark.parametrize("radius", [0.018, 0.025, 0.045])
def test_a_sphere_bends_by_one_over_its_radius(radius: float) -> None:
    probe = SurfaceCurvature(trimesh.creation.icosphere(subdivisions=4, radius=radius))
    point = np.array([0.0, 0.6, 0.8]) * radius
    assert probe.at(point, point / radius) == pytest.approx(1.0 / radius, rel=0.1)


def test_a_cylinder_reads_its_round_direction_and_a_box_its_faces_and_edges() -> None:
    cylinder = SurfaceCurvature(trimesh.creation.cylinder(radius=0.02, height=0.08, sections=64))
    assert cylinder.at(np.array([0.02, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])) == pytest.approx(
        50.0, rel=0.1
    )
    box = SurfaceCurvature(trimesh.creation.box(extents=(0.05, 0.06, 0.04)))
    assert box.at(np.array([0.0, 0.0, 0.02]), np.array([0.0, 0.0, 1.0])) < 1.0
    edge = box.at(np.array([0.025, 0.0, 0.02]), np.array([1.0, 0.0, 1.0]))
    assert curvature_bin(edge) == "R < 12 mm"
    assert np.isnan(box.at(np.array([0.5, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])))  # off it
    with pytest.raises(ValueError, match="radius"):
        SurfaceCurvature(trimesh.creation.box(), radius=0.0)


def test_bins_and_the_manifest_table(tmp_path: Path) -> None:
    assert [curvature_bin(k) for k in (0.0, 20.0, 40.0, 500.0, float("nan"))] == [
        "R >= 80 mm",
        "R 30-80 mm",
        "R 12-30 mm",
        "R < 12 mm",
        "unknown",
    ]
    paths = [str(tmp_path / "index" / "wood" / f"{i:05d}.png") for i in range(3)]
    assert curvature_bins(tmp_path, paths) is None  # no manifest: real data
    table = {"index/wood/00000.png": 40.0, "index/wood/00001.png": None}
    (tmp_path / "manifest.json").write_text(json.dumps({"curvatures": table}))
    assert curvature_bins(tmp_path, paths).tolist() == ["R 12-30 mm", "unknown", "unknown"]
