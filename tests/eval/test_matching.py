"""The 3D matching percentage on a two-material sphere with exactly known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.eval.matching import MatchingEvaluator, sample_faces_uniform
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from tests.eval.objects import (
    CAP_Z,
    CLASSES,
    predict_by_y,
    predict_swap_x_positive,
    two_material_sphere,
)


@pytest.fixture(scope="module")
def sphere() -> MaterialObject:
    return two_material_sphere()


def test_samples_lie_in_the_regions_of_interest(sphere: MaterialObject) -> None:
    ev = MatchingEvaluator(sphere, num_samples=5000, seed=0)
    assert ev.points.shape == (5000, 3) and ev.labels.shape == (5000,)
    assert not (ev.labels == IGNORE).any()
    assert set(np.unique(ev.labels)) == {0, 2}
    np.testing.assert_allclose(np.linalg.norm(ev.points, axis=1), 0.05, atol=1e-3)
    # Samples sit on their faces' plane (no caps: every face top is below the cap height).
    assert np.abs(ev.points[:, 2]).max() <= CAP_Z + 1e-3


def test_perfect_predictor_scores_exactly_100(sphere: MaterialObject) -> None:
    ev = MatchingEvaluator(sphere, num_samples=20000, seed=0)
    assert ev.score(predict_by_y) == 100.0
    assert ev.per_class(predict_by_y) == {"plastic": 100.0, "fabric": 100.0}


def test_swapping_one_hemisphere_scores_half(sphere: MaterialObject) -> None:
    ev = MatchingEvaluator(sphere, num_samples=20000, seed=0)
    score = ev.score(predict_swap_x_positive)
    # Binomial sampling: std = 100 * sqrt(0.25 / 20000) = 0.35 points.
    assert score == pytest.approx(50.0, abs=1.5)
    # Exact against the samples themselves.
    assert score == pytest.approx(100.0 * np.mean(ev.points[:, 0] < 0))
    per_class = ev.per_class(predict_swap_x_positive)
    assert set(per_class) == {"plastic", "fabric"}
    for value in per_class.values():
        assert value == pytest.approx(50.0, abs=2.5)
    result = ev.evaluate(predict_swap_x_positive)
    assert result["matching_pct"] == score and result["matching_per_class"] == per_class
    assert result["matching_mean_class_pct"] == pytest.approx(np.mean(list(per_class.values())))


def test_ignore_faces_never_count(sphere: MaterialObject) -> None:
    ev = MatchingEvaluator(sphere, num_samples=20000, seed=0)
    roi_faces = sphere.mesh.faces[sphere.face_labels != IGNORE]
    z_max = np.abs(sphere.mesh.vertices[roi_faces][..., 2]).max()

    def wrong_on_caps(points: np.ndarray) -> np.ndarray:
        return np.where(np.abs(points[:, 2]) > z_max + 1e-9, 3, predict_by_y(points))

    # Wrong everywhere on the ignored caps, right inside the regions of interest.
    caps, _ = trimesh.sample.sample_surface(sphere.mesh, 2000, seed=0)
    assert (wrong_on_caps(caps) == 3).any()
    assert ev.score(wrong_on_caps) == 100.0
    # A constant prediction scores the plastic area share only.
    plastic_share = 100.0 * np.mean(ev.labels == 0)
    assert ev.score(lambda x: np.zeros(len(x), dtype=np.int64)) == pytest.approx(plastic_share)


def test_same_seed_same_samples_other_seed_other_samples(sphere: MaterialObject) -> None:
    a = MatchingEvaluator(sphere, num_samples=3000, seed=4)
    b = MatchingEvaluator(sphere, num_samples=3000, seed=4)
    c = MatchingEvaluator(sphere, num_samples=3000, seed=5)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert not np.allclose(a.points, c.points)
    assert a.score(predict_swap_x_positive) == b.score(predict_swap_x_positive)


def test_sampling_is_area_uniform() -> None:
    # Box 1 x 2 x 4 cm: the top face (1 x 2) has 1/4 of the area of the +x face (2 x 4).
    box = trimesh.creation.box(extents=(0.01, 0.02, 0.04))
    normals = box.face_normals
    labels = np.full(len(box.faces), IGNORE)
    labels[normals[:, 2] > 0.9] = 0
    labels[normals[:, 0] > 0.9] = 1
    obj = MaterialObject("box", box, labels, CLASSES)
    ev = MatchingEvaluator(obj, num_samples=40000, seed=1)
    assert np.mean(ev.labels == 0) == pytest.approx(0.2, abs=0.01)
    # Inside a face: uniform too (mean of the top face's samples is its centre).
    top = ev.points[ev.labels == 0]
    np.testing.assert_allclose(top[:, :2].mean(axis=0), 0.0, atol=2e-4)
    np.testing.assert_allclose(top[:, 2], 0.02, atol=1e-12)


def test_sample_faces_uniform_rejects_zero_area() -> None:
    vertices = np.zeros((3, 3))
    with pytest.raises(ValueError, match="zero total area"):
        sample_faces_uniform(vertices, np.array([[0, 1, 2]]), np.array([0]), 10, 0)


def test_object_without_regions_of_interest_raises_no_data(sphere: MaterialObject) -> None:
    obj = MaterialObject(
        "all_ignored", sphere.mesh, np.full(len(sphere.mesh.faces), IGNORE), CLASSES
    )
    with pytest.raises(NoDataError, match="all_ignored"):
        MatchingEvaluator(obj)


@pytest.mark.parametrize(
    "bad",
    [
        lambda x: np.zeros((len(x), 1), dtype=np.int64),
        lambda x: np.zeros(len(x) - 1, dtype=np.int64),
        lambda x: np.zeros(len(x)),
    ],
)
def test_bad_predictor_output_is_a_value_error(sphere: MaterialObject, bad) -> None:
    ev = MatchingEvaluator(sphere, num_samples=100)
    with pytest.raises(ValueError, match="predictor"):
        ev.score(bad)
