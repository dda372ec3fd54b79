"""map_errors' trained-point figures: how right the readings the map trained on are, and
what the same points would map read perfectly."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.bench.map_errors import (
    USED_POINT_FIGURES,
    used_point_truth,
    wrong_trained_points,
)
from neuralfeels_sem.eval.error_sources import TouchSet
from neuralfeels_sem.eval.matching import MatchingEvaluator
from tests.eval.objects import RADIUS, two_material_sphere
from tests.eval.test_error_sources import FABRIC, PLASTIC, _press


@pytest.fixture(scope="module")
def sphere():
    obj = two_material_sphere()
    return obj, MatchingEvaluator(obj, num_samples=4000, seed=0)


def test_used_points_are_judged_by_their_truth_and_mapped_read_perfectly(sphere) -> None:
    obj, matching = sphere
    plastic, fabric = _press(+1.0), _press(-1.0)
    # The fabric press is read wrong on a quarter of its points; a third press is unused.
    fabric_read = np.full(32, FABRIC)
    fabric_read[:8] = PLASTIC
    touches = TouchSet(
        [plastic, fabric, _press(-1.0, x=0.5)],
        [PLASTIC, FABRIC, PLASTIC],
        [True, True, False],
        used_point_labels=[np.full(32, PLASTIC), fabric_read, np.full(32, -1)],
    )
    got = used_point_truth(obj, matching, touches)
    assert got["used_point_accuracy_pct"] == pytest.approx(100.0 * 56 / 64)
    # Read perfectly, one press on each side gives every sample its side's material.
    assert got["nearest_used_point_truth_mean_class_pct"] == pytest.approx(100.0)


def test_without_trained_points_the_figures_are_none(sphere) -> None:
    obj, matching = sphere
    empty = dict.fromkeys(USED_POINT_FIGURES)
    assert used_point_truth(obj, matching, TouchSet([], [], [])) == empty
    unused = TouchSet([_press(1.0)], [PLASTIC], [False])
    assert used_point_truth(obj, matching, unused) == empty


def test_abstentions_are_the_unlabelled_touches_with_a_reading() -> None:
    import torch

    from neuralfeels_sem.bench.map_errors import abstentions
    from neuralfeels_sem.mapping.touch_memory import TouchBuffer

    buffer = TouchBuffer(torch.device("cpu"), None)
    points = torch.tensor(_press(1.0), dtype=torch.float32)
    axis = torch.tensor([0.0, 1.0, 0.0])
    edge_reading = torch.tensor([0.97, 0.01, 0.01, 0.01])
    buffer.add(points, axis, PLASTIC, 1.0, probs=torch.tensor([0.9, 0.1, 0.0, 0.0]))
    buffer.add(points, axis, -1, 1.0, probs=edge_reading, at_edge=True)
    buffer.add(points, axis, -1, 1.0)  # geometry only: no reading kept
    mapper = type("Mapper", (), {"memory": type("Memory", (), {"touches": buffer})})()
    got = abstentions(mapper)
    assert len(got.points) == 1 and got.at_edge.tolist() == [True]
    np.testing.assert_allclose(got.probs, edge_reading[None].numpy())
    empty = type(
        "Mapper",
        (),
        {"memory": type("Memory", (), {"touches": TouchBuffer(torch.device("cpu"), None)})},
    )()
    assert len(abstentions(empty).points) == 0


def test_pooled_lines_name_each_figure(sphere) -> None:
    from neuralfeels_sem.bench.map_errors import pooled_lines
    from neuralfeels_sem.eval.reading_audit import Abstentions, pool_audits, reading_audit

    obj, _ = sphere
    touches = TouchSet([_press(+1.0), _press(-1.0)], [PLASTIC, PLASTIC], [True, False])
    audit = reading_audit(obj, touches, Abstentions([], [], []), list(obj.class_names))
    text = pooled_lines(pool_audits([audit]))
    assert "readings the vote left out: 1, right   0 %" in text
    assert "abstained (edge)" in text and "naming a material the map nearly lacks: 0" in text


def _across(y_from: float, y_to: float) -> np.ndarray:
    """32 contact points of a press at +x on the equator, from y_from to y_to (radians)."""
    direction = np.column_stack([np.ones(32), np.linspace(y_from, y_to, 32), np.zeros(32)])
    return RADIUS * direction / np.linalg.norm(direction, axis=1, keepdims=True)


def test_wrong_trained_points_are_told_apart_by_their_press(sphere) -> None:
    obj, _ = sphere
    split = np.full(32, FABRIC)
    split[:8] = PLASTIC  # a press whose patches disagree, a quarter of it wrongly
    presses = [
        (_press(+1.0), np.full(32, PLASTIC)),  # right throughout
        (_across(-0.15, 0.15), np.full(32, PLASTIC)),  # one label over the border
        (_across(-0.15, 0.15), np.full(32, PLASTIC)),  # the same, an edge imprint
        (_press(-1.0), split),
        (_press(-1.0, x=0.5), np.full(32, PLASTIC)),  # misread on one material
        (_across(-0.005, 0.305), np.full(32, PLASTIC)),  # one point past the border
    ]
    touches = TouchSet(
        [p for p, _ in presses],
        [int(lab[0]) for _, lab in presses],
        [True] * len(presses),
        used_point_labels=[lab for _, lab in presses],
    )
    at_edge = np.array([False, False, True, False, False, False])
    got = wrong_trained_points(obj, touches, at_edge)
    assert got == {
        "split": 8,
        "across_border": 16,
        "across_border_at_edge": 16,
        "misread": 32,
        "other": 1,
    }


def test_the_right_points_map_leaves_out_wrong_and_ignored_points(sphere) -> None:
    obj, matching = sphere
    plastic, fabric = _press(+1.0), _press(-1.0)
    # A fabric press read as plastic throughout: the plastic label wins the south too.
    touches = TouchSet(
        [plastic, fabric, _press(-1.0, x=0.5)],
        [PLASTIC, FABRIC, PLASTIC],
        [True, True, True],
        used_point_labels=[np.full(32, PLASTIC), np.full(32, FABRIC), np.full(32, PLASTIC)],
    )
    got = used_point_truth(obj, matching, touches)
    assert got["used_point_accuracy_pct"] == pytest.approx(100.0 * 64 / 96)
    assert got["nearest_right_point_mean_class_pct"] == pytest.approx(100.0)
    assert got["used_points_ignored_pct"] == pytest.approx(0.0)


def test_points_on_ignored_faces_are_counted_apart(sphere) -> None:
    obj, matching = sphere
    ignored = np.flatnonzero(obj.face_labels < 0)  # the sphere's polar caps
    seam = obj.mesh.triangles_center[ignored[:8]]
    assert len(seam) == 8
    touches = TouchSet(
        [_press(+1.0), seam],
        [PLASTIC, PLASTIC],
        [True, True],
        used_point_labels=[np.full(32, PLASTIC), np.full(len(seam), PLASTIC)],
    )
    got = used_point_truth(obj, matching, touches)
    assert got["used_points_ignored_pct"] == pytest.approx(100.0 * len(seam) / (32 + len(seam)))
