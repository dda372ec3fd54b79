"""Uncertainty of the material map: entropy, AUROC and ECE on constructed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from neuralfeels_sem.eval.uncertainty import (
    auroc,
    entropy_of_probabilities,
    expected_calibration_error,
    uncertainty_scores,
)
from neuralfeels_sem.fields.material_uncertainty import normalised_entropy


def test_entropy_is_zero_for_a_sure_class_and_one_for_a_uniform_softmax() -> None:
    logits = torch.tensor(
        [[50.0, -50.0, -50.0, -50.0], [1.0, 1.0, 1.0, 1.0], [0.0, 0.0, -1e9, -1e9]]
    )
    entropy = normalised_entropy(logits)
    assert entropy[0].item() == pytest.approx(0.0, abs=1e-6)
    assert entropy[1].item() == pytest.approx(1.0, abs=1e-6)
    # two equally likely classes of four: log 2 / log 4
    assert entropy[2].item() == pytest.approx(0.5, abs=1e-6)
    probs = torch.softmax(logits, dim=-1).numpy()
    np.testing.assert_allclose(entropy_of_probabilities(probs), entropy.numpy(), atol=1e-6)


def test_entropy_of_a_known_softmax() -> None:
    probs = np.array([[0.7, 0.2, 0.1]])
    expected = -(0.7 * math.log(0.7) + 0.2 * math.log(0.2) + 0.1 * math.log(0.1)) / math.log(3)
    assert entropy_of_probabilities(probs)[0] == pytest.approx(expected)
    assert normalised_entropy(torch.log(torch.tensor(probs))).item() == pytest.approx(expected)
    with pytest.raises(ValueError, match="C >= 2"):
        normalised_entropy(torch.zeros(3, 1))


def test_auroc_of_a_separating_a_random_and_a_hand_computed_score() -> None:
    wrong = np.array([0, 0, 0, 1, 1], dtype=bool)
    assert auroc(np.array([0.1, 0.2, 0.3, 0.8, 0.9]), wrong) == 1.0
    assert auroc(np.array([0.9, 0.8, 0.7, 0.2, 0.1]), wrong) == 0.0
    # Pairs (wrong, right) with the wrong one ranked higher: 0.5 beats 0.1 and 0.3 and ties
    # 0.5 (one half); 0.2 beats 0.1 only: (2.5 + 1) / 6.
    assert auroc(np.array([0.1, 0.3, 0.5, 0.5, 0.2]), wrong) == pytest.approx(3.5 / 6)
    rng = np.random.default_rng(0)
    assert auroc(rng.random(20000), rng.random(20000) < 0.3) == pytest.approx(0.5, abs=0.02)
    assert auroc(np.array([0.1, 0.2]), np.array([False, False])) is None


def test_ece_of_calibrated_and_overconfident_predictions() -> None:
    # 10 samples at confidence 0.8 of which 8 are right: calibrated.
    confidence = np.full(10, 0.8)
    assert expected_calibration_error(confidence, np.arange(10) < 8) == pytest.approx(0.0)
    # Half at 0.95 all right (gap 0.05), half at 0.55 with 1 of 5 right (gap 0.35): 0.2.
    confidence = np.r_[np.full(5, 0.95), np.full(5, 0.55)]
    correct = np.r_[np.ones(5, bool), np.arange(5) < 1]
    assert expected_calibration_error(confidence, correct) == pytest.approx(0.2)
    # A confidence of exactly 1 sits in the last bin, of 0 in the first.
    assert expected_calibration_error(np.array([1.0, 0.0]), np.array([True, False])) == 0.0


def test_uncertainty_scores_name_a_map_without_errors() -> None:
    probs = np.array([[0.9, 0.1], [0.6, 0.4], [0.2, 0.8], [0.55, 0.45]])
    labels = np.array([0, 1, 1, 0])  # the second is wrong, and the most uncertain but one
    scores = uncertainty_scores(probs, labels)
    entropy = entropy_of_probabilities(probs)
    assert scores["auroc"] == pytest.approx(2 / 3)  # beats 0.9 and 0.8, loses to 0.55
    assert scores["mean_entropy_wrong"] == pytest.approx(entropy[1])
    assert scores["mean_entropy_correct"] == pytest.approx(entropy[[0, 2, 3]].mean())
    assert scores["mean_entropy"] == pytest.approx(entropy.mean())
    assert scores["error_share"] == 0.25 and "note" not in scores
    perfect = uncertainty_scores(probs, probs.argmax(axis=1))
    assert perfect["auroc"] is None and perfect["mean_entropy_wrong"] is None
    assert "every one of the 4 samples is right" in perfect["note"]
    assert perfect["ece"] >= 0.0
