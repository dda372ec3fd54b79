"""F-score and Chamfer distance on meshes with known distances."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.eval.shape import precision_recall_fscore, shape_metrics


def sphere(radius: float, subdivisions: int = 5) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def test_identical_meshes_score_perfectly() -> None:
    mesh = sphere(0.05)
    result = shape_metrics(mesh, mesh, num_samples=5000)
    assert result["fscore_5mm"] == 1.0
    assert result["precision_5mm"] == 1.0 and result["recall_5mm"] == 1.0
    assert result["chamfer_mm"] == 0.0
    assert [t for t, _ in result["fscore_curve"]] == [float(t) for t in range(1, 21)]
    assert all(f == 1.0 for _, f in result["fscore_curve"])


def test_same_surface_other_triangulation_is_near_zero() -> None:
    a = trimesh.creation.uv_sphere(radius=0.05, count=[64, 64])
    b = sphere(0.05)
    result = shape_metrics(a, b, num_samples=20000)
    assert result["fscore_5mm"] == 1.0
    assert result["chamfer_mm"] < 1.0  # sample-spacing floor, about 0.6 mm here


def test_sphere_3mm_larger() -> None:
    result = shape_metrics(
        sphere(0.053), sphere(0.05), num_samples=20000, thresholds_mm=[1, 2, 5, 10]
    )
    assert result["chamfer_mm"] == pytest.approx(3.0, abs=0.4)
    assert result["chamfer_mm"] >= 3.0 - 0.05  # every sample of one lies >= ~3 mm from the other
    assert result["fscore_5mm"] == 1.0
    curve = dict((t, f) for t, f in result["fscore_curve"])
    assert curve[1.0] == 0.0 and curve[2.0] == 0.0
    assert curve[5.0] == 1.0 and curve[10.0] == 1.0


def test_precision_and_recall_are_not_swapped() -> None:
    # Prediction: the GT sphere plus a far-away blob (extra surface lowers precision only).
    gt = sphere(0.05, 4)
    blob = sphere(0.01, 3)
    blob.apply_translation([0.3, 0, 0])
    pred = trimesh.util.concatenate([gt, blob])
    result = shape_metrics(pred, gt, num_samples=20000)
    blob_share = blob.area / pred.area
    assert result["recall_5mm"] == pytest.approx(1.0, abs=0.01)
    assert result["precision_5mm"] == pytest.approx(1.0 - blob_share, abs=0.01)


def test_fscore_formula() -> None:
    d_pred = np.array([0.001, 0.002, 0.01, 0.02])
    d_gt = np.array([0.001, 0.01])
    p, r, f = precision_recall_fscore(d_pred, d_gt, 0.005)
    assert (p, r) == (0.5, 0.5)
    assert f == pytest.approx(0.5)
    assert precision_recall_fscore(d_pred, d_gt, 0.0005) == (0.0, 0.0, 0.0)


def test_empty_mesh_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="predicted mesh is empty"):
        shape_metrics(trimesh.Trimesh(), sphere(0.05))
