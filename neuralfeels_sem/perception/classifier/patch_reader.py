"""Reading touches patch by patch: which crops of each imprint the classifier sees, and
how their readings become each contact pixel's material (patches.py holds the geometry)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.classifier.gates import check_patch_reading
from neuralfeels_sem.perception.classifier.patches import (
    crop_around,
    crop_contact_share,
    patch_centres,
    pixel_labels,
)
from neuralfeels_sem.perception.touch import NO_LABEL, TouchLabel

# (N, H, W, 3) crops -> (N, C) class probabilities
Predict = Callable[[np.ndarray], np.ndarray]


@dataclass
class PatchReader:
    """The classifier's patch settings (classifier.patch_*, classifier.max_patches).

    spacing_px: crops at most this far apart across the imprint (0: one label per touch).
    max_patches: at most this many crops per touch, the centroid's included.
    probe: patches read first after the centre (the imprint's far ends); a touch whose
        centre and probes all name one material confidently is taken as that material
        throughout (0: read every patch).
    min_contact: a patch past the centroid is centred only where its crop holds at least
        this share of imprint (0: anywhere on the contact).
    disagree_confidence: a patch naming another material than the touch's (centre) label
        needs at least this confidence, else it abstains (at or below min_confidence: off).
    """

    spacing_px: int = 0
    max_patches: int = 8
    probe: int = 0
    min_contact: float = 0.0
    disagree_confidence: float = 0.0

    def __post_init__(self) -> None:
        check_patch_reading(
            self.spacing_px, self.max_patches, self.probe, self.min_contact,
            self.disagree_confidence,
        )  # fmt: skip
        self.spacing_px, self.max_patches = int(self.spacing_px), int(self.max_patches)
        self.probe, self.min_contact = int(self.probe), float(self.min_contact)
        self.disagree_confidence = float(self.disagree_confidence)

    def read(
        self,
        readings: Sequence[TactileReading],
        masks: list[np.ndarray],
        labels: list[TouchLabel],
        predict: Predict,
        crop_px: int,
        min_confidence: float,
    ) -> None:
        """Fill `pixel_labels` of each touch from crops across its imprint.

        The first centre is the contact's centroid, whose crop the touch's own label read.
        The next `probe` centres are read first, in one batch for all touches; only the
        touches not taken as one material throughout have their remaining patches read (a
        second batch). A labelled edge imprint's patches naming another material abstain:
        the edge streak trusted its label's material only (edge_streak.py).
        """
        if not readings:
            return
        centres = [self.centres(m, crop_px) for m in masks]
        probe = self.probe if self.probe > 0 else self.max_patches
        batch = _Batch(predict, crop_px, len(labels[0].probs))
        first = batch.read(readings, centres, 1, 1 + probe)
        probs = [np.concatenate([lab.probs[None], p]) for lab, p in zip(labels, first)]
        rest = [
            i for i, p in enumerate(probs)
            if len(p) < len(centres[i]) and not _uniform(p, min_confidence)
        ]  # fmt: skip
        later = batch.read([readings[i] for i in rest], [centres[i] for i in rest], 1 + probe)
        for i, p in zip(rest, later):
            probs[i] = np.concatenate([probs[i], p])
        for reading, cs, label, p in zip(readings, centres, labels, probs):
            top, conf = p.argmax(axis=1), p.max(axis=1)
            top = np.where(conf >= min_confidence, top, NO_LABEL)
            if label.label != NO_LABEL:  # naming another material than the centre's
                bar = (conf < self.disagree_confidence) | label.at_edge
                top = np.where((top != label.label) & bar, NO_LABEL, top)
            if len(p) < len(cs):  # one material throughout: the unread patches take it
                top = np.full(len(cs), top[0])
                conf = np.full(len(cs), conf.min(), dtype=conf.dtype)
            label.pixel_labels, label.pixel_confidence = pixel_labels(
                reading.image.shape[:2], cs, top, conf, crop_px / 2.0
            )

    def centre_only(self, reading: TactileReading, mask: np.ndarray, label: TouchLabel,
                    crop_px: int) -> None:  # fmt: skip
        """Label only the pixels within the centroid crop's reach (the crop the label read)."""
        centre = patch_centres(mask, self.spacing_px, 1)  # the centroid alone
        label.pixel_labels, label.pixel_confidence = pixel_labels(
            reading.image.shape[:2], centre, np.array([label.label]),
            np.array([label.confidence]), crop_px / 2.0,
        )  # fmt: skip

    def centres(self, mask: np.ndarray, crop_px: int) -> np.ndarray:
        """The touch's patch centres; past the centroid only where the crop holds at least
        `min_contact` of imprint."""
        eligible = None
        if self.min_contact > 0:
            eligible = crop_contact_share(mask, crop_px) >= self.min_contact
        return patch_centres(mask, self.spacing_px, self.max_patches, eligible)


def _uniform(probs: np.ndarray, min_confidence: float) -> bool:
    """All readings (K, C) confident and naming one material."""
    top = probs.argmax(axis=1)
    return bool((probs.max(axis=1) >= min_confidence).all() and (top == top[0]).all())


@dataclass
class _Batch:
    """Reads the crops of several touches in one call of the classifier."""

    predict: Predict
    crop_px: int
    num_classes: int

    def read(
        self,
        readings: Sequence[TactileReading],
        centres: list[np.ndarray],
        start: int,
        stop: int | None = None,
    ) -> list[np.ndarray]:
        """Per reading, the (k, C) probabilities of its crops at centres[start:stop]."""
        chosen = [cs[start:stop] for cs in centres]
        crops = [
            crop_around(r.image, c, self.crop_px) for r, cs in zip(readings, chosen) for c in cs
        ]
        if not crops:
            return [np.zeros((0, self.num_classes)) for _ in chosen]
        flat = self.predict(np.stack(crops))
        bounds = np.cumsum([0] + [len(cs) for cs in chosen])
        return [flat[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
