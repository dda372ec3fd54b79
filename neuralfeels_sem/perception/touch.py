"""What the material classifier says about one touch; what the mapper trains on."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NO_LABEL = -1


@dataclass
class TouchLabel:
    """Classification of one tactile frame.

    `label` is a class index into the config's `materials`, or NO_LABEL when the frame
    shows no contact or the prediction is below the confidence threshold (it is then
    marked `low_confidence` rather than forced to a class).
    """

    finger: str
    contact: bool
    label: int = NO_LABEL
    confidence: float = 0.0  # probability of the predicted class
    probs: np.ndarray | None = None  # (C,) class probabilities, None without contact
    low_confidence: bool = False

    @property
    def usable(self) -> bool:
        """True when the touch may train the material branch."""
        return self.contact and self.label != NO_LABEL and not self.low_confidence
