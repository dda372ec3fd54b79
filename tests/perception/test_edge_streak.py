"""EdgeStreak: an imprint along the border keeps its label only after the same finger read
the same material confidently on the frames just before."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.edge_streak import EdgeStreak
from neuralfeels_sem.perception.touch import NO_LABEL
from tests.perception.synthetic_tactile import CLASSES, background, pressed
from tests.perception.test_classifier_infer import reading


def test_streak_counts_consecutive_confident_readings_per_finger() -> None:
    streak = EdgeStreak(frames=2, confidence=0.99)
    assert not streak.trusted("index", 1, 0.999)  # nothing read before
    streak.update("index", 1, 0.995)
    assert not streak.trusted("index", 1, 0.999)  # one frame is not a streak of two
    streak.update("index", 1, 0.999)
    assert streak.trusted("index", 1, 0.999)
    assert not streak.trusted("index", 2, 0.999)  # another material
    assert not streak.trusted("index", 1, 0.98)  # the reading itself not confident
    assert not streak.trusted("thumb", 1, 0.999)  # another finger's streak
    streak.update("index", 1, 0.5)  # an unsure frame ends the streak
    assert not streak.trusted("index", 1, 0.999)
    streak.update("index", 1, 0.999)
    streak.update("index", 1, 0.999)
    streak.update("index", None, 0.0)  # so does a frame out of contact
    assert not streak.trusted("index", 1, 0.999)
    streak.update("index", 3, 0.999)
    streak.update("index", 1, 0.999)  # a change of material starts a new streak
    assert not streak.trusted("index", 1, 0.999)
    assert not EdgeStreak(frames=0).trusted("index", 1, 1.0)  # off


def test_an_edge_reading_confident_enough_is_trusted_alone() -> None:
    streak = EdgeStreak(frames=2, confidence=0.99, alone=0.995)
    assert streak.trusted("index", 1, 0.995)  # no streak needed at that confidence
    assert not streak.trusted("index", 1, 0.994)  # below it, the streak rule as before
    assert EdgeStreak(frames=0, alone=0.9).trusted("ring", 0, 0.95)  # with the streak off too


def test_bad_settings_are_value_errors() -> None:
    with pytest.raises(ValueError, match="edge_streak_frames"):
        EdgeStreak(frames=-1)
    with pytest.raises(ValueError, match="edge_streak_confidence"):
        EdgeStreak(confidence=0.0)
    with pytest.raises(ValueError, match="classifier.edge_streak_frames"):
        EfficientNetClassifierConfig(edge_streak_frames=-2)
    with pytest.raises(ValueError, match="classifier.edge_streak_confidence"):
        EfficientNetClassifierConfig(edge_streak_confidence=1.5)
    with pytest.raises(ValueError, match="edge_long_streak_frames"):
        EdgeStreak(frames=-1, name="edge_long_streak")
    with pytest.raises(ValueError, match="classifier.edge_long_streak_frames"):
        EfficientNetClassifierConfig(edge_long_streak_frames=-1)
    with pytest.raises(ValueError, match="classifier.edge_long_streak_confidence"):
        EfficientNetClassifierConfig(edge_long_streak_confidence=0.0)
    with pytest.raises(ValueError, match="edge_min_confidence"):
        EdgeStreak(alone=0.0)
    with pytest.raises(ValueError, match="classifier.edge_min_confidence"):
        EfficientNetClassifierConfig(edge_min_confidence=1.2)


def one_hot(top: int, confidence: float) -> np.ndarray:
    p = np.full(len(CLASSES), (1.0 - confidence) / (len(CLASSES) - 1), np.float32)
    p[top] = confidence
    return p


def edge_strip(bg: np.ndarray) -> np.ndarray:
    """A frame whose contact lies only along the sensor's border."""
    strip = bg.astype(np.int16)
    strip[100:220, 222:] += 60
    return np.clip(strip, 0, 255).astype(np.uint8)


def scripted(checkpoint: Path, queue: list[np.ndarray], **streaks) -> MaterialClassifier:
    """A classifier whose network answers with the probabilities queued, in order."""
    clf = MaterialClassifier(
        CLASSES, checkpoint=str(checkpoint), device="cpu", patch_spacing_px=0,
        edge_streak_frames=2, edge_streak_confidence=0.99, **streaks,
    )  # fmt: skip
    clf.predict_images = lambda images, backgrounds: np.stack([queue.pop(0) for _ in images])
    return clf


def test_classifier_labels_an_edge_imprint_backed_by_the_fingers_streak(
    untrained_checkpoint: Path,
) -> None:
    bg = background(0)
    strip = edge_strip(bg)
    centred = pressed(0, 1, np.random.default_rng(2))
    queue: list[np.ndarray] = []
    clf = scripted(untrained_checkpoint, queue)

    def read(image: np.ndarray, top: int, confidence: float):
        queue.append(one_hot(top, confidence))
        return clf.classify([reading("index", image, bg)])[0]

    assert read(strip, 1, 0.999).label == NO_LABEL  # an edge imprint alone: no label
    assert read(centred, 1, 0.995).usable
    edge = read(strip, 1, 0.999)  # after two confident metal frames (the first an edge one)
    assert edge.usable and edge.at_edge and edge.label == 1 and edge.weight == 1.0
    assert read(strip, 2, 0.999).label == NO_LABEL  # names another material
    read(centred, 1, 0.995)
    read(centred, 1, 0.9)  # labelled, but not confident enough to extend the streak
    assert read(strip, 1, 0.999).label == NO_LABEL


def test_a_long_streak_below_the_short_ones_bar_backs_an_edge_imprint(
    untrained_checkpoint: Path,
) -> None:
    bg = background(0)
    strip = edge_strip(bg)
    queue: list[np.ndarray] = []
    long = {"edge_long_streak_frames": 3, "edge_long_streak_confidence": 0.8}
    clf = scripted(untrained_checkpoint, queue, **long)

    def read(top: int, confidence: float):
        queue.append(one_hot(top, confidence))
        return clf.classify([reading("ring", strip, bg)])[0]

    # a finger sliding along a small part: edge readings of one material, none at 0.99
    assert [read(0, c).label for c in (0.85, 0.9, 0.82)] == [NO_LABEL] * 3
    fourth = read(0, 0.88)  # three frames before it at >= 0.8: backed
    assert fourth.usable and fourth.label == 0 and fourth.weight == 1.0
    assert read(1, 0.95).label == NO_LABEL  # another material starts a new streak
    assert read(1, 0.95).label == NO_LABEL
    read(1, 0.7)  # below the long streak's bar: the streak ends
    assert [read(1, 0.9).label for _ in range(3)] == [NO_LABEL] * 3
    assert read(1, 0.9).label == 1
    off = scripted(untrained_checkpoint, queue)  # the long streak off (its class default)
    for _ in range(6):
        queue.append(one_hot(0, 0.9))
        assert off.classify([reading("ring", strip, bg)])[0].label == NO_LABEL  # off: never
