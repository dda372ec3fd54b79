"""Press fusion: a label for touches the classifier abstained on, from the presses around them.

The classifier abstains on a touch it reads below `classifier.min_confidence` (or along the
sensor's edge). On a small part of another material, that is often all the part gets:
two presses each at 0.7 for fabric teach the map nothing, though together they say fabric
far more surely than either. Here the class probabilities of every touch that has them
are pooled over the presses whose centroid lies within `radius` of an abstained touch
(the frames of one press averaged first, in log-probability, so one long press counts
once), as independent readings of one place:

    log p(c | presses) = sum over presses of mean log p(c | frames of the press) + const

and the abstained touch takes the top class when at least `min_presses` presses
contributed and its pooled probability reaches `confidence`. A label, once fused, stays
(the evidence only grows); the label vote (label_vote.py) still judges it like any other.
The settings are MapperConfig's `fuse_*` (mapping/mapper.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig

# Probabilities are floored here before the logs are summed: one press that rules a class
# out completely (a saturated softmax) must not veto every other press.
PROB_FLOOR = 1e-3


@dataclass(frozen=True)
class PressFusion:
    """The fusion's settings (defaults: MapperConfig's `fuse_*`); radius 0 switches it off.

    radius: metres between touch centroids for presses to be pooled.
    min_presses: distinct presses (the abstained touch's own included) that must contribute.
    confidence: pooled probability the top class needs.
    weight: the fused label's weight in the material loss, times its pooled probability.
    include_edge: whether touches abstained on for lying along the sensor's edge are
        labelled and pool their probabilities (their readings are often confidently wrong).
    press_gap: a finger's touches at most this many mapped frames apart are one press
        (the label vote's `label_vote_press_gap`).
    """

    radius: float
    min_presses: int
    confidence: float
    weight: float
    include_edge: bool
    press_gap: int

    def __post_init__(self) -> None:
        if self.radius < 0:
            raise ValueError(f"mapping.mapper.fuse_radius={self.radius} must be >= 0 (0: off)")
        if self.min_presses < 2:
            raise ValueError(
                f"mapping.mapper.fuse_min_presses={self.min_presses} must be >= 2 "
                "(one press is what the classifier already judged)"
            )
        if not 0.0 < self.confidence <= 1.0 or not 0.0 < self.weight <= 1.0:
            raise ValueError(
                f"mapping.mapper.fuse_confidence={self.confidence} and fuse_weight={self.weight} "
                "must be in (0, 1]"
            )

    @classmethod
    def from_config(cls, config: MapperConfig) -> PressFusion:
        return cls(
            radius=float(config.fuse_radius),
            min_presses=int(config.fuse_min_presses),
            confidence=float(config.fuse_confidence),
            weight=float(config.fuse_weight),
            include_edge=bool(config.fuse_edge),
            press_gap=int(config.label_vote_press_gap),
        )

    @property
    def active(self) -> bool:
        return self.radius > 0.0

    def fuse(
        self,
        centroids: torch.Tensor,
        probs: torch.Tensor,
        events: torch.Tensor,
        candidates: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Fused labels of the candidate touches: (K,) class (-1: none) and (K,) probability.

        centroids (T, 3) and probs (T, C) of the touches that have class probabilities,
        events (T,) their press ids (label_vote.press_events), candidates (K,) indices of
        the abstained ones to label.
        """
        if centroids.ndim != 2 or centroids.shape[1] != 3 or probs.shape[:1] != centroids.shape[:1]:
            raise ValueError(
                f"expected (T, 3) centroids and (T, C) probs, got {centroids.shape}, {probs.shape}"
            )
        if events.shape != centroids.shape[:1]:
            raise ValueError(f"expected (T,) press ids, got {events.shape}")
        k = len(candidates)
        if k == 0:
            return torch.full((0,), -1, dtype=torch.long), torch.zeros(0)
        near = (torch.cdist(centroids[candidates], centroids) < self.radius).to(probs.dtype)
        _, press = torch.unique(events, return_inverse=True)
        members = torch.nn.functional.one_hot(press).to(probs.dtype)  # (T, P)
        frames = near @ members  # (K, P) frames of each press near each candidate
        logp = probs.clamp_min(PROB_FLOOR).log()
        summed = torch.einsum("kt,tp,tc->kpc", near, members, logp)
        per_press = summed / frames.clamp_min(1.0)[..., None]
        pooled = torch.softmax(per_press.sum(1), dim=1)  # presses without frames add 0
        top, label = pooled.max(1)
        presses = (frames > 0).sum(1)
        ok = (presses >= self.min_presses) & (top >= self.confidence)
        return torch.where(ok, label, -1), torch.where(ok, top, 0.0)
