"""Classifier accuracy bookkeeping during a run, against hand-counted answers."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.eval.classifier_metrics import ClassifierAccuracy, gt_material_of, never_read

CLASSES = list(DEFAULT_MATERIALS)


def test_hand_made_sequence() -> None:
    acc = ClassifierAccuracy()
    sequence = [
        ("index", 0, 0),  # right
        ("index", 0, 0),  # right
        ("index", 1, 0),  # wrong
        ("index", -1, 0),  # abstained
        ("index", 2, None),  # no ground truth: not judged
        ("thumb", 3, 3),  # right
        ("thumb", 0, 3),  # wrong
        ("thumb", 2, 2),  # right
        ("thumb", -1, 2),  # abstained
    ]
    for finger, predicted, gt in sequence:
        acc.update(finger, predicted, gt)
    s = acc.summary(CLASSES)
    assert s["overall"] == pytest.approx(4 / 6)
    assert s["per_finger"] == {"index": pytest.approx(2 / 3), "thumb": pytest.approx(2 / 3)}
    assert s["per_material"] == {"plastic": pytest.approx(2 / 3), "fabric": 1.0, "wood": 0.5}
    assert s["per_finger_material"] == {
        "index": {"plastic": pytest.approx(2 / 3)},
        "thumb": {"fabric": 1.0, "wood": 0.5},
    }
    assert s["counts"]["index"]["plastic"] == {
        "accuracy": pytest.approx(2 / 3),
        "coverage": pytest.approx(3 / 4),
        "accuracy_all_touches": pytest.approx(2 / 4),
        "correct": 2,
        "judged": 3,
        "abstentions": 1,
        "touches": 4,
    }
    # Abstentions count as not correctly labelled in accuracy_all_touches, never in accuracy.
    assert s["coverage"] == pytest.approx(6 / 8)
    assert s["accuracy_all_touches"] == pytest.approx(4 / 8)
    assert s["by_finger"]["thumb"]["coverage"] == pytest.approx(3 / 4)
    assert s["by_finger"]["thumb"]["accuracy_all_touches"] == pytest.approx(2 / 4)
    assert s["by_material"]["wood"] == {
        "accuracy": 0.5,
        "coverage": 1.0,
        "accuracy_all_touches": 0.5,
        "correct": 1,
        "judged": 2,
        "abstentions": 0,
        "touches": 2,
    }
    assert s["by_material"]["fabric"]["coverage"] == 0.5
    assert s["counts"]["thumb"]["fabric"]["abstentions"] == 1
    assert s["abstentions"] == 2
    assert s["judged"] == 6
    assert s["abstention_rate"] == pytest.approx(2 / 8)
    assert s["no_ground_truth"] == {"index": 1}


def test_a_material_only_ever_abstained_has_no_accuracy() -> None:
    acc = ClassifierAccuracy()
    acc.update("ring", -1, 1)
    s = acc.summary(CLASSES)
    assert s["overall"] is None
    assert s["per_finger_material"] == {"ring": {"metal": None}}
    assert s["abstentions"] == 1 and s["abstention_rate"] == 1.0
    # The weak-finger effect shows: no coverage and nothing correct, not a missing cell.
    assert s["coverage"] == 0.0 and s["accuracy_all_touches"] == 0.0
    assert s["by_finger"]["ring"]["coverage"] == 0.0


def test_empty_summary() -> None:
    s = ClassifierAccuracy().summary(CLASSES)
    assert s["overall"] is None and s["per_finger"] == {} and s["abstention_rate"] is None


def test_bad_classes_are_value_errors() -> None:
    acc = ClassifierAccuracy()
    with pytest.raises(ValueError, match="predicted"):
        acc.update("index", -3, 0)
    with pytest.raises(ValueError, match="ground-truth"):
        acc.update("index", 0, -1)
    acc.update("index", 0, 7)
    with pytest.raises(ValueError, match="outside class_names"):
        acc.summary(CLASSES)


def reading(mask: np.ndarray | None, material: np.ndarray | None) -> TactileReading:
    return TactileReading(
        finger="index",
        image=np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH, 3), dtype=np.uint8),
        world_T_sensor=np.eye(4),
        intrinsics=Intrinsics.from_fov(DIGIT_WIDTH, DIGIT_HEIGHT, 60.0),
        gt_contact_mask=mask,
        gt_material=material,
    )


def test_gt_material_is_the_majority_under_the_contact() -> None:
    mask = np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH), dtype=bool)
    material = np.full(
        (DIGIT_HEIGHT, DIGIT_WIDTH), 3, dtype=np.int16
    )  # wood everywhere off contact
    mask[:10, :10] = True
    material[:10, :10] = 2
    material[:10, :3] = 1  # 30 metal pixels vs 70 fabric inside the contact
    assert gt_material_of(reading(mask, material)) == 2
    material[:10, :5] = -1  # half the contact over an ignored region
    material[:10, 5:] = 0
    assert gt_material_of(reading(mask, material)) == 0


def test_a_touch_mostly_outside_the_regions_of_interest_has_no_ground_truth() -> None:
    mask = np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH), dtype=bool)
    material = np.full((DIGIT_HEIGHT, DIGIT_WIDTH), -1, dtype=np.int16)
    mask[:10, :10] = True
    material[:10, :4] = 1  # 40 metal pixels at the rim of an ignored bottom
    assert gt_material_of(reading(mask, material)) is None


def test_gt_material_is_none_without_contact_or_ground_truth() -> None:
    mask = np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH), dtype=bool)
    material = np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH), dtype=np.int16)
    assert gt_material_of(reading(mask, material)) is None
    assert gt_material_of(reading(None, None)) is None
    mask[5, 5] = True
    material[5, 5] = -1
    assert gt_material_of(reading(mask, material)) is None


def test_never_read_names_each_material_no_touch_read_rightly_and_why() -> None:
    acc = ClassifierAccuracy()
    for finger, predicted, gt in [
        ("index", 0, 0),  # plastic: read rightly
        ("ring", -1, 1),  # metal: pressed, abstained
        ("thumb", 0, 3),  # wood: read as plastic
        ("middle", 2, None),  # no ground truth: says nothing about fabric
    ]:
        acc.update(finger, predicted, gt)
    summary = acc.summary(CLASSES)
    assert never_read(summary, CLASSES) == {
        "metal": "never labelled",
        "fabric": "never pressed",
        "wood": "never read rightly",
    }
    assert never_read(summary, ["plastic"]) == {}
    assert never_read(summary, []) is None  # no material present: no matching samples
    nothing = ClassifierAccuracy()
    nothing.update("index", 0, None)  # a real rig: no touch has a ground truth
    assert never_read(nothing.summary(CLASSES), CLASSES) is None
