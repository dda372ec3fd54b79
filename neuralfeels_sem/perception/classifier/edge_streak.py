"""Per finger, how many frames in a row the classifier has named one material confidently.

An imprint along the sensor's border (a tilted pad's edge) is misread often enough that
its reading gets no label (classifier.max_edge_share). But where the same finger has named
the same material confidently on the frames just before, the edge reading is one more frame
of a contact the classifier already reads steadily: on the development objects (30 s runs,
mapping seeds 0-2) edge readings at confidence >= 0.99 were right 83 % of the time alone,
and 97 % after two such frames of the same finger naming the same material.

A finger sliding over a small part often reads it at the gel's edge for many frames in a
row below 0.99 (0.68-0.987 over the ten frames of the insert traced), so a second streak,
longer at a lower bar, backs those readings (classifier.edge_long_streak_*): on the
generated development set (objects 100-119, mapping seeds 0-1) the edge readings left
without a label that followed four frames naming their material at >= 0.8 were right
96.9 % of the time (1079 frames).
"""

from __future__ import annotations

from dataclasses import dataclass, field

# The two streaks' settings' prefixes (for error messages).
SHORT_STREAK, LONG_STREAK = "classifier.edge_streak", "classifier.edge_long_streak"


def check_streak(name: str, frames: int, confidence: float) -> None:
    """A streak's settings: `name`_frames >= 0 (0: off), `name`_confidence in (0, 1]."""
    if frames < 0:
        raise ValueError(f"{name}_frames={frames} must be >= 0 (0: off)")
    if not 0.0 < confidence <= 1.0:
        raise ValueError(f"{name}_confidence={confidence} must be in (0, 1]")


def check_alone(alone: float | None) -> None:
    """classifier.edge_min_confidence: in (0, 1] or None (off)."""
    if alone is not None and not 0.0 < alone <= 1.0:
        raise ValueError(f"classifier.edge_min_confidence={alone} must be in (0, 1] or null (off)")


@dataclass
class EdgeStreak:
    """Counts each finger's run of consecutive confident readings naming one material.

    `frames` 0 is off: `trusted` is then always False.
    """

    frames: int = 0
    confidence: float = 0.99
    # An edge reading at or above this probability is trusted on its own (None: never): a
    # model adapted to the rig's own edge imprints (bench/rig_touches.py) reads them so.
    alone: float | None = None
    name: str = SHORT_STREAK  # the settings' prefix, for error messages
    _runs: dict[str, tuple[int, int]] = field(default_factory=dict)  # finger -> (label, run)

    def __post_init__(self) -> None:
        self.frames, self.confidence = int(self.frames), float(self.confidence)
        check_streak(self.name, self.frames, self.confidence)
        check_alone(self.alone)

    def trusted(self, finger: str, top: int, confidence: float) -> bool:
        """True when this reading (top class, its probability) follows at least `frames`
        confident readings of `top` by the same finger on the frames just before, or is
        itself at least `alone`."""
        if self.alone is not None and confidence >= self.alone:
            return True
        label, run = self._runs.get(finger, (-1, 0))
        return (
            self.frames > 0
            and confidence >= self.confidence
            and label == top
            and run >= self.frames
        )

    def update(self, finger: str, top: int | None, confidence: float) -> None:
        """Record this frame's reading of `finger` (`top` None: no contact), after `trusted`."""
        if top is None or confidence < self.confidence:
            self._runs.pop(finger, None)
            return
        label, run = self._runs.get(finger, (-1, 0))
        self._runs[finger] = (top, run + 1 if label == top else 1)
