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
    # The imprint lies mostly along the sensor's border (classifier.max_edge_share): the
    # reading is not trusted, whatever its confidence.
    at_edge: bool = False
    # Patch readings (classifier.patch_spacing_px > 0, perception/classifier/patches.py):
    # per contact pixel, the material of the nearest patch the classifier read (NO_LABEL:
    # none) and that patch's confidence, both (H, W). None: one label for the whole touch.
    pixel_labels: np.ndarray | None = None
    pixel_confidence: np.ndarray | None = None
    # How much the map trusts the label beside its confidence: below 1 for an imprint
    # along the sensor's border read at classifier.edge_label_weight.
    weight: float = 1.0

    @property
    def usable(self) -> bool:
        """True when the touch's own label may train the material branch."""
        return self.contact and self.label != NO_LABEL and not self.low_confidence

    @property
    def has_pixel_labels(self) -> bool:
        """True when patch readings give some contact pixel a material."""
        return (
            self.contact
            and self.pixel_labels is not None
            and bool((self.pixel_labels != NO_LABEL).any())
        )


def abstention(label: TouchLabel) -> str:
    """Why a touch in contact got no label: `edge` (the imprint lies along the sensor's
    border), `low_confidence` (below classifier.min_confidence), or "" when it has one."""
    if not label.contact or label.usable:
        return ""
    return "edge" if label.at_edge else "low_confidence"
