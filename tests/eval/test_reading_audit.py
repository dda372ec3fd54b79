"""The reading audit: frames read rightly per material, the vote's left-out readings, and
the abstained presses, judged against the ground truth of a two-material sphere."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.eval.error_sources import TouchSet
from neuralfeels_sem.eval.reading_audit import (
    Abstentions,
    majority_truth,
    pool_audits,
    reading_audit,
)
from tests.eval.objects import RADIUS, two_material_sphere
from tests.eval.test_error_sources import FABRIC, PLASTIC, _press

CLASSES = list(two_material_sphere().class_names)
METAL = 1  # a material the sphere does not have


@pytest.fixture(scope="module")
def sphere():
    return two_material_sphere()


def _polar_press() -> np.ndarray:
    """Contact points on the ignored polar cap: no ground truth to judge by."""
    angles = np.linspace(-0.05, 0.05, 32)
    direction = np.column_stack([angles, angles, np.ones(32)])
    return RADIUS * direction / np.linalg.norm(direction, axis=1, keepdims=True)


def test_majority_truth_ignores_the_ignored_faces(sphere) -> None:
    assert majority_truth(sphere, _press(+1.0)) == PLASTIC
    assert majority_truth(sphere, _press(-1.0)) == FABRIC
    assert majority_truth(sphere, _polar_press()) == -1


def test_readings_are_judged_per_material_and_by_what_the_vote_kept(sphere) -> None:
    # Touches: plastic read right and kept (x2), fabric read right but left out, fabric
    # misread as plastic and left out, a border touch read half plastic half fabric (patch
    # readings, both kept, both right), and one on the polar cap (not judged).
    border = np.concatenate([_press(+1.0)[:16], _press(-1.0)[:16]])
    split = np.r_[np.full(16, PLASTIC), np.full(16, FABRIC)]
    points = [_press(+1.0), _press(+1.0, x=0.3), _press(-1.0), _press(-1.0, x=0.3), border]
    points.append(_polar_press())
    read = [np.full(32, PLASTIC), np.full(32, PLASTIC), np.full(32, FABRIC)]
    read += [np.full(32, PLASTIC), split, np.full(32, FABRIC)]
    used = [read[0], read[1], np.full(32, -1), np.full(32, -1), split, np.full(32, -1)]
    touches = TouchSet(
        points,
        [r[0] for r in read],
        [u.max() >= 0 for u in used],
        point_labels=read,
        used_point_labels=used,
    )
    abstained = Abstentions([], np.zeros((0, 4)), [])
    recall = {"plastic": 97.0, "fabric": 12.0}
    audit = reading_audit(sphere, touches, abstained, CLASSES, recall)
    fabric, plastic = audit["per_material"]["fabric"], audit["per_material"]["plastic"]
    assert (plastic["frames_right"], plastic["frames_right_kept"]) == (3, 3)
    assert plastic["frames_naming_it_wrongly"] == 1
    assert (fabric["frames_right"], fabric["frames_right_kept"]) == (2, 1)
    assert fabric["map_recall_pct"] == 12.0
    assert audit["per_material"]["metal"]["map_recall_pct"] is None
    # Left out: the right fabric reading and the misreading; the polar one is not judged.
    assert audit["outvoted"] == {"readings": 2, "right": 1, "right_pct": 50.0}


def test_abstained_presses_are_binned_by_confidence_and_reason(sphere) -> None:
    presses = [_press(+1.0), _press(+1.0, x=0.3), _press(-1.0), _press(-1.0, x=0.3)]
    probs = np.zeros((5, 4))
    probs[0, PLASTIC] = 1.0  # edge, sure and right
    probs[1, FABRIC] = 0.95  # edge, wrong
    probs[1, PLASTIC] = 0.05
    probs[2, METAL] = 0.995  # low confidence?: no, an edge reading of a material not there
    probs[2, FABRIC] = 0.005
    probs[3, FABRIC], probs[3, PLASTIC] = 0.6, 0.4  # below confidence, right
    probs[4, PLASTIC] = 1.0  # on the ignored cap: not judged
    abstained = Abstentions(presses + [_polar_press()], probs, [True, True, True, False, True])
    kept = TouchSet([_press(+1.0)], [PLASTIC], [True])
    audit = reading_audit(sphere, kept, abstained, CLASSES)
    edge = {row["from"]: row for row in audit["abstained_by_confidence"]["edge"]}
    assert (edge[0.9999]["frames"], edge[0.9999]["right"]) == (1, 1)  # 1.0 is in the top bin
    assert (edge[0.9]["frames"], edge[0.9]["right"]) == (1, 0)
    assert (edge[0.99]["frames"], edge[0.99]["right"]) == (1, 0)
    low = {row["from"]: row for row in audit["abstained_by_confidence"]["low_confidence"]}
    assert (low[0.0]["frames"], low[0.0]["right"]) == (1, 1)
    assert sum(row["frames"] for row in low.values()) == 1
    # Confident readings of a material with under RARE_KEPT kept readings: the metal one
    # and the sure plastic one (one kept plastic reading only): one right of two.
    assert audit["abstained_rare_material"] == {"frames": 2, "right": 1, "right_pct": 50.0}


def test_audits_pool_over_runs_and_materials_bin_by_frames_read_rightly(sphere) -> None:
    once = TouchSet([_press(-1.0)], [FABRIC], [False])
    many = TouchSet([_press(+1.0, x=0.02 * i) for i in range(12)], [PLASTIC] * 12, [True] * 12)
    empty = Abstentions([], [], [])
    audits = [
        reading_audit(sphere, once, empty, CLASSES, {"plastic": 0.0, "fabric": 4.0}),
        reading_audit(sphere, many, empty, CLASSES, {"plastic": 96.0, "fabric": 0.0}),
    ]
    pooled = pool_audits(audits)
    bins = {row["from"]: row for row in pooled["materials_by_frames_right"]}
    # 0-1 frames: plastic of run one (0), fabric of both (1 and 0); 10+: plastic of run two
    assert bins[0]["materials"] == 3 and bins[0]["mean_recall_pct"] == pytest.approx(4.0 / 3)
    assert bins[10]["materials"] == 1 and bins[10]["mean_recall_pct"] == 96.0
    assert bins[2]["materials"] == 0 and bins[2]["mean_recall_pct"] is None
    assert pooled["outvoted"] == {"readings": 1, "right": 1, "right_pct": 100.0}
    assert pooled["abstained_rare_material"]["right_pct"] is None


def test_mismatched_abstentions_are_value_errors() -> None:
    with pytest.raises(ValueError, match="flags"):
        Abstentions([_press(1.0)], np.ones((1, 4)), [True, False])
    with pytest.raises(ValueError, match="readings"):
        Abstentions([_press(1.0), _press(-1.0)], np.ones(4), [True, False])


def test_a_sliver_of_another_material_is_not_a_reading(sphere) -> None:
    # Two of 32 points read fabric: under READ_SHARE, as the mapper's vote counts reads.
    read = np.full(32, PLASTIC)
    read[:2] = FABRIC
    touches = TouchSet([_press(+1.0)], [PLASTIC], [True], point_labels=[read])
    audit = reading_audit(sphere, touches, Abstentions([], [], []), CLASSES)
    assert audit["per_material"]["plastic"]["frames_right"] == 1
    assert audit["per_material"]["fabric"]["frames_naming_it_wrongly"] == 0
