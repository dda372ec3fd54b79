"""Mean-class, IoU and shape-aware matching, and the majority baseline, with known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.eval.matching import NO_PREDICTION, MatchingEvaluator, label_scores
from neuralfeels_sem.eval.mesh_transfer import labels_from_mesh
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from tests.eval.objects import CLASSES, RADIUS, predict_by_y, two_material_sphere


def test_hand_counted_scores() -> None:
    # 8 plastic, 2 fabric; the map gets 7 plastic and 1 fabric right.
    labels = np.array([0] * 8 + [2] * 2)
    pred = np.array([0] * 7 + [2] + [2, 0])
    s = label_scores(labels, pred, CLASSES)
    assert s["matching_pct"] == pytest.approx(80.0)
    assert s["matching_per_class"] == {"plastic": pytest.approx(87.5), "fabric": 50.0}
    assert s["matching_mean_class_pct"] == pytest.approx((87.5 + 50.0) / 2)
    # IoU plastic: 7 / (8 + 1) ; fabric: 1 / (2 + 1).
    assert s["matching_miou_pct"] == pytest.approx(100 * (7 / 9 + 1 / 3) / 2)


def test_a_constant_map_scores_its_share_but_only_one_class_in_the_mean() -> None:
    labels = np.array([2] * 96 + [0] * 4)  # a plushie: 96 % fabric
    s = label_scores(labels, np.full(100, 2), CLASSES)
    assert s["matching_pct"] == pytest.approx(96.0)
    assert s["matching_mean_class_pct"] == pytest.approx(50.0)
    assert s["matching_miou_pct"] == pytest.approx(48.0)  # fabric 96 %, plastic 0 %


def test_no_prediction_is_wrong_for_every_class() -> None:
    labels = np.array([0, 0, 2, 2])
    s = label_scores(labels, np.array([0, NO_PREDICTION, 2, NO_PREDICTION]), CLASSES)
    assert s["matching_pct"] == 50.0 and s["matching_mean_class_pct"] == 50.0
    assert s["matching_miou_pct"] == 50.0
    with pytest.raises(ValueError, match="do not match"):
        label_scores(labels, np.zeros(3, np.int64), CLASSES)


def test_majority_class_and_single_class_note() -> None:
    sphere = two_material_sphere()
    ev = MatchingEvaluator(sphere, num_samples=5000, seed=0)
    assert ev.majority_class == int(np.bincount(ev.labels).argmax()) and ev.notes == []
    labels = np.where(sphere.face_labels == IGNORE, IGNORE, 1)
    one = MaterialObject("metal_sphere", sphere.mesh, labels, CLASSES)
    ev = MatchingEvaluator(one, num_samples=500, seed=0)
    assert ev.majority_class == 1
    assert len(ev.notes) == 1 and "one material (metal)" in ev.notes[0]
    s = ev.evaluate(lambda x: np.full(len(x), 1))
    assert s["matching_mean_class_pct"] == 100.0 == s["matching_per_class"]["metal"]


def labelled_mesh(mesh: trimesh.Trimesh, label_of) -> trimesh.Trimesh:
    mesh = mesh.copy()
    mesh.vertex_attributes["label"] = label_of(np.asarray(mesh.vertices))
    return mesh


def test_mesh_transfer_on_the_true_surface_matches_the_field_form() -> None:
    sphere = two_material_sphere()
    ev = MatchingEvaluator(sphere, num_samples=4000, seed=0)
    mesh = labelled_mesh(trimesh.creation.icosphere(subdivisions=5, radius=RADIUS), predict_by_y)
    labels, distance = labels_from_mesh(mesh, ev.points, 0.005)
    assert distance.max() < 0.5e-3
    # Only samples within a triangle's width of the y = 0 border can take the other side's label.
    mesh_pct = ev.evaluate_labels(labels)["matching_pct"]
    assert ev.score(predict_by_y) == 100.0 and mesh_pct > 99.0


def test_a_misplaced_or_missing_surface_costs_matching() -> None:
    sphere = two_material_sphere()
    ev = MatchingEvaluator(sphere, num_samples=4000, seed=0)
    ico = trimesh.creation.icosphere(subdivisions=5, radius=RADIUS)
    # 3 mm too small: within the 5 mm tolerance, labels still transfer.
    small = labelled_mesh(ico.copy().apply_scale((RADIUS - 0.003) / RADIUS), predict_by_y)
    assert ev.evaluate_labels(labels_from_mesh(small, ev.points, 0.005)[0])["matching_pct"] > 99
    # 1 cm off to the side: the far half of the samples has no surface within 5 mm.
    moved = labelled_mesh(ico.copy().apply_translation((0.01, 0, 0)), predict_by_y)
    labels, distance = labels_from_mesh(moved, ev.points, 0.005)
    lost = np.mean(labels == NO_PREDICTION)
    assert lost == pytest.approx(np.mean(distance > 0.005)) and 0.2 < lost < 0.8
    assert ev.evaluate_labels(labels)["matching_pct"] == pytest.approx(100 * (1 - lost), abs=1.0)
    # Only the y > 0 half reconstructed: the fabric half is lost whatever the field says.
    keep = ico.triangles_center[:, 1] > 0.0
    half = labelled_mesh(trimesh.Trimesh(ico.vertices, ico.faces[keep]), predict_by_y)
    s = ev.evaluate_labels(labels_from_mesh(half, ev.points, 0.005)[0])
    # (fabric samples within 5 mm of the cut, ~6 % of the half, still find the border vertices)
    assert s["matching_per_class"]["fabric"] < 10.0 and s["matching_per_class"]["plastic"] > 98.0


def test_mesh_transfer_refuses_bad_input() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=RADIUS)
    with pytest.raises(ValueError, match="label"):
        labels_from_mesh(mesh, np.zeros((3, 3)), 0.005)
    mesh = labelled_mesh(mesh, predict_by_y)
    for tolerance in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="mesh_match_tolerance_m"):
            labels_from_mesh(mesh, np.zeros((3, 3)), tolerance)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        labels_from_mesh(mesh, np.zeros((3, 2)), 0.005)


def test_a_mesh_far_from_the_samples_costs_no_more_memory_than_a_near_one() -> None:
    """A run whose tracked pose drifted scores a mesh centimetres from the samples: every
    sample gets NO_PREDICTION at distance inf, without gathering every face for every
    sample (trimesh's query did: a 24 GB run was killed for it)."""
    import tracemalloc

    sphere = two_material_sphere()
    ev = MatchingEvaluator(sphere, num_samples=4000, seed=0)
    ico = trimesh.creation.icosphere(subdivisions=6, radius=RADIUS)  # 81 920 faces
    far = labelled_mesh(ico.apply_translation((0.2, 0.0, 0.0)), predict_by_y)
    tracemalloc.start()
    labels, distance = labels_from_mesh(far, ev.points, 0.005)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert (labels == NO_PREDICTION).all() and np.isinf(distance).all()
    assert peak < 200e6, peak
