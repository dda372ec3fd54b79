"""A classifier that reads the simulator's ground truth: for ablations and debugging.

It answers what a perfect tactile classifier would: the majority ground-truth material
under the contact patch. It needs sim ground truth and says so on real data.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.touch import NO_LABEL, TouchLabel


class OracleClassifier:
    """Majority of `gt_material` over `gt_contact_mask`; confidence = that majority's share."""

    def __init__(self, class_names: Sequence[str], min_confidence: float = 0.0) -> None:
        if not 0.0 <= min_confidence <= 1.0:
            raise ValueError(f"min_confidence={min_confidence} must be in [0, 1]")
        self.class_names = list(class_names)
        self.min_confidence = float(min_confidence)

    def open(self) -> OracleClassifier:
        return self

    def classify(self, readings: Sequence[TactileReading]) -> list[TouchLabel]:
        return [self._classify_one(r) for r in readings]

    def _classify_one(self, reading: TactileReading) -> TouchLabel:
        if reading.gt_contact_mask is None or reading.gt_material is None:
            raise ConfigError(
                f"classifier=oracle needs simulator ground truth, but the {reading.finger} frame has none; "
                "use classifier=efficientnet_b0 on real data"
            )
        mask = reading.gt_contact_mask.astype(bool)
        if not mask.any():
            return TouchLabel(finger=reading.finger, contact=False)
        classes = reading.gt_material[mask].astype(np.int64)
        classes = classes[(classes >= 0) & (classes < len(self.class_names))]
        if classes.size == 0:  # touching only regions outside the ground truth's classes
            return TouchLabel(finger=reading.finger, contact=True)
        probs = (
            np.bincount(classes, minlength=len(self.class_names)).astype(np.float32) / classes.size
        )
        top = int(probs.argmax())
        low = bool(probs[top] < self.min_confidence)
        return TouchLabel(
            finger=reading.finger,
            contact=True,
            label=NO_LABEL if low else top,
            confidence=float(probs[top]),
            probs=probs,
            low_confidence=low,
        )
