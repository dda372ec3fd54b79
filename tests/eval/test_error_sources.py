"""Error sources of a material map: each wrong sample charged to its region's case."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.eval.error_sources import TouchSet, error_sources, face_regions
from neuralfeels_sem.eval.matching import MatchingEvaluator
from tests.eval.objects import RADIUS, predict_by_y, two_material_sphere

PLASTIC, FABRIC = 0, 2


def _press(y_sign: float, x: float = 0.0) -> np.ndarray:
    """32 contact points of a press on the sphere's equator on the y side `y_sign`."""
    angles = np.linspace(-0.15, 0.15, 32)
    direction = np.column_stack([x + angles, np.full(32, y_sign), np.zeros(32)])
    return RADIUS * direction / np.linalg.norm(direction, axis=1, keepdims=True)


@pytest.fixture(scope="module")
def sphere():
    obj = two_material_sphere()
    return obj, MatchingEvaluator(obj, num_samples=4000, seed=0)


def _sources(sphere, touches: TouchSet, predicted: np.ndarray | None = None) -> dict:
    obj, matching = sphere
    if predicted is None:  # everything plastic: every fabric sample wrong
        predicted = np.zeros(len(matching.points), dtype=np.int64)
    return error_sources(obj, matching.points, matching.faces, predicted, touches)


def test_regions_are_connected_faces_of_one_material() -> None:
    obj = two_material_sphere()
    regions = face_regions(obj)
    assert set(np.unique(regions)) == {-1, 0, 1}
    assert np.all((regions == -1) == (obj.face_labels == -1))
    for r in (0, 1):
        assert len(np.unique(obj.face_labels[regions == r])) == 1


@pytest.mark.parametrize(
    ("fabric_label", "fabric_used", "case"),
    [
        (None, None, "unpressed"),
        (-1, False, "abstained"),
        (FABRIC, False, "outvoted"),
        (PLASTIC, True, "mislabelled"),
    ],
)
def test_a_wrong_region_is_charged_to_what_its_presses_gave(
    sphere, fabric_label, fabric_used, case
) -> None:
    points, labels, used = [_press(1.0)], [PLASTIC], [True]
    if fabric_label is not None:
        points.append(_press(-1.0))
        labels.append(fabric_label)
        used.append(fabric_used)
    report = _sources(sphere, TouchSet(points, np.array(labels), np.array(used)))
    fabric_samples = int(np.sum(sphere[1].labels == FABRIC))
    assert report["wrong_samples"] == fabric_samples
    # All of fabric wrong, all of plastic right: half of mean-class matching is lost.
    assert report["mean_class_points_lost"] == pytest.approx(50.0)
    assert report["by_case"][case]["mean_class_points_lost"] == pytest.approx(50.0)
    assert sum(c["wrong_samples"] for c in report["by_case"].values()) == fabric_samples
    fabric = [r for r in report["regions"] if r["material"] == "fabric"]
    assert fabric[0]["case"] == case and fabric[0]["recall_pct"] == 0.0


def test_errors_of_a_supported_region_are_binned_by_distance_to_a_right_press(sphere) -> None:
    _, matching = sphere
    touches = TouchSet(
        [_press(1.0), _press(-1.0)], np.array([PLASTIC, FABRIC]), np.array([True, True])
    )
    right = predict_by_y(matching.points)
    assert _sources(sphere, touches, right)["wrong_samples"] == 0
    # Wrong where x > 2 cm on the fabric side: at least 2 cm from the fabric press at x = 0.
    wrong = (matching.points[:, 1] < 0) & (matching.points[:, 0] > 0.02)
    report = _sources(sphere, touches, np.where(wrong, PLASTIC, right))
    assert report["by_case"]["supported"]["wrong_samples"] == int(wrong.sum())
    bins = report["supported_distance_m"]
    assert bins["<0.5cm"] == bins["<1cm"] == 0
    assert sum(bins.values()) == int(wrong.sum())


def test_touch_set_checks_its_lengths() -> None:
    with pytest.raises(ValueError, match="touches"):
        TouchSet([_press(1.0)], np.array([0, 1]), np.array([True]))


def test_a_touch_with_point_labels_supports_each_region_its_points_name(sphere) -> None:
    # One press across the border at y = 0: its points on either side read their own side.
    angles = np.linspace(-0.3, 0.3, 64)
    across = RADIUS * np.column_stack([np.ones(64), angles, np.zeros(64)])
    across /= np.linalg.norm(across, axis=1, keepdims=True) / RADIUS
    point_labels = [np.where(across[:, 1] > 0, PLASTIC, FABRIC)]
    touches = TouchSet([across], np.array([PLASTIC]), np.array([True]), point_labels)
    report = _sources(sphere, touches)
    assert {r["material"]: r["case"] for r in report["regions"]} == {
        "plastic": "supported",
        "fabric": "supported",
    }
    plain = _sources(sphere, TouchSet([across], np.array([PLASTIC]), np.array([True])))
    assert {r["material"]: r["case"] for r in plain["regions"]}["fabric"] == "mislabelled"
    with pytest.raises(ValueError, match="point_labels"):
        TouchSet([across], np.array([0]), np.array([True]), [np.zeros(3)])


def test_a_reading_the_vote_left_out_does_not_support_its_region(sphere) -> None:
    # A used press across the border whose fabric reading the vote left out: the fabric
    # side was read rightly but nothing trained on it, so the region counts as outvoted.
    angles = np.linspace(-0.3, 0.3, 64)
    across = RADIUS * np.column_stack([np.ones(64), angles, np.zeros(64)])
    across /= np.linalg.norm(across, axis=1, keepdims=True) / RADIUS
    read = np.where(across[:, 1] > 0, PLASTIC, FABRIC)
    used = np.where(read == PLASTIC, PLASTIC, -1)
    touches = TouchSet([across], np.array([PLASTIC]), np.array([True]), [read], [used])
    cases = {r["material"]: r["case"] for r in _sources(sphere, touches)["regions"]}
    assert cases == {"plastic": "supported", "fabric": "outvoted"}
    with pytest.raises(ValueError, match="used_point_labels"):
        TouchSet([across], np.array([0]), np.array([True]), [read], [np.zeros(3)])
