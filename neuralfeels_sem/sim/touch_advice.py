"""The map's touch advice (sensor.policy=active): a score of object-frame points.

`TouchAdvice`, built after every mapped frame by the mapping session's touch advisor
(pipeline/touch_advisor.py), scores object-frame points:

  base(p)  = (w_u * u(p) + w_n * novelty(p)) / (w_u + w_n)
  score(p) = base(p) + c * confirm(p) * (1 - base(p))   in [0, 1]

  u(p):       normalised entropy of the material branch at the map's surface sample
              nearest p (fields/material_uncertainty.py); 1 where no sample lies within
              `unseen_m` (a part the map has not seen is as uncertain as can be); with
              `boundary_m` set, at least border(p) (below);
  border(p):  1 - (d_other(p) - d_1(p)) / boundary_m, clipped to [0, 1]: d_1 is the
              distance to the nearest labelled touch and d_other to the nearest one with
              another label. The map's fill gives every point the nearest touch's label
              with a confidence that fades with d_1 alone, so it is as sure halfway between
              two materials' presses as beside one; the border between them lies somewhere
              there, and this term marks the band where a press would place it;
  novelty(p): distance from p to the nearest labelled touch, over `novelty_m`, capped at 1
              (1 before any touch): an untrained branch is often confidently wrong, so
              entropy alone would not send the fingers to parts never pressed;
  confirm(p): 1 within `confirm_m` of a reading the label vote left out that no other
              press has touched near (TouchBuffer.unconfirmed_readings), else 0: a small
              part read once is left out of the map until a second press backs it, and a
              second press there settles it either way. c = `confirm_weight` in [0, 1]
              (0: off) lifts such a point that share of the way to 1; every other point
              keeps its score, so the regrasp threshold means what it did.

The touch planner (sim/touch_planner.py) ranks reachable touches by this score.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass
class TouchScoreConfig:
    """`mapping.advisor.score`: the weights of the touch score (see the module docstring)."""

    uncertainty_weight: float = 1.0
    novelty_weight: float = 1.0
    novelty_m: float = 0.03  # a point this far from every labelled touch is fully novel
    unseen_m: float = 0.01  # a point this far from the map's surface samples counts unknown
    confirm_weight: float = 0.0  # in [0, 1]; 0: off
    confirm_m: float = 0.01  # a point this close to an unconfirmed reading confirms it
    # Width (m) of the band between two labels' touches that counts as uncertain (the
    # border term of the module docstring); null: off, the map's entropy alone.
    boundary_m: float | None = None

    def __post_init__(self) -> None:
        if self.uncertainty_weight < 0 or self.novelty_weight < 0:
            raise ValueError(
                "mapping.advisor.score: uncertainty_weight and novelty_weight must be >= 0"
            )
        if not 0.0 <= self.confirm_weight <= 1.0:
            raise ValueError(
                f"mapping.advisor.score.confirm_weight={self.confirm_weight} must be in [0, 1]"
            )
        if self.confirm_m <= 0:
            raise ValueError(f"mapping.advisor.score.confirm_m={self.confirm_m} must be > 0")
        if self.uncertainty_weight + self.novelty_weight <= 0:
            raise ValueError(
                "mapping.advisor.score: set uncertainty_weight or novelty_weight above 0"
            )
        if self.novelty_m <= 0 or self.unseen_m <= 0:
            raise ValueError("mapping.advisor.score: novelty_m and unseen_m must be > 0 (metres)")
        if self.boundary_m is not None and self.boundary_m <= 0:
            raise ValueError(
                f"mapping.advisor.score.boundary_m={self.boundary_m} must be > 0 or null"
            )


class TouchAdvice:
    """The map's advice after one frame: scores object-frame points (numpy only, immutable).

    Args:
        surface: (M, 3) samples of the map's surface, object frame (metres).
        entropy: (M,) normalised entropy of the material branch there, in [0, 1].
        touched: (T, 3) labelled touches so far, object frame.
        config: the score's weights.
        frame_index: the mapped frame this advice follows.
        unconfirmed: (K, 3) readings left out by the vote, to be confirmed, object frame.
        normals: (M, 3) the map's outward unit normals at the surface samples, object frame
            (None: unknown; a chosen turn then ignores which way a sample faces).
        labels: (T,) the class each touch in `touched` was read as (negative: none), for
            the border term (None: unknown; the term then stays 0).
    """

    def __init__(
        self,
        surface: np.ndarray,
        entropy: np.ndarray,
        touched: np.ndarray,
        config: TouchScoreConfig,
        frame_index: int,
        unconfirmed: np.ndarray | None = None,
        normals: np.ndarray | None = None,
        labels: np.ndarray | None = None,
    ) -> None:
        surface = np.asarray(surface, np.float64).reshape(-1, 3)
        entropy = np.asarray(entropy, np.float64).reshape(-1)
        if len(surface) != len(entropy):
            raise ValueError(f"{len(surface)} surface samples but {len(entropy)} entropies")
        if normals is not None:
            normals = np.asarray(normals, np.float64).reshape(-1, 3)
            if len(normals) != len(surface):
                raise ValueError(f"{len(surface)} surface samples but {len(normals)} normals")
        self.normals = normals
        self.surface, self.entropy = surface, np.clip(entropy, 0.0, 1.0)
        self.touched = np.asarray(touched, np.float64).reshape(-1, 3)
        self.config, self.frame_index = config, int(frame_index)
        self._surface_tree = cKDTree(surface) if len(surface) else None
        self._touch_tree = cKDTree(self.touched) if len(self.touched) else None
        self.unconfirmed = np.asarray(
            np.zeros((0, 3)) if unconfirmed is None else unconfirmed, np.float64
        ).reshape(-1, 3)
        self._confirm_tree = cKDTree(self.unconfirmed) if len(self.unconfirmed) else None
        # Built only for the border term: the advice is remade after every mapped frame.
        self._label_trees = (
            _label_trees(self.touched, labels) if config.boundary_m is not None else []
        )

    def touch_distance(self, points: np.ndarray) -> np.ndarray:
        """(N,) metres from each point to the nearest labelled touch (inf before any)."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if self._touch_tree is None:
            return np.full(len(points), np.inf)
        return self._touch_tree.query(points)[0]

    def uncertainty(self, points: np.ndarray) -> np.ndarray:
        """(N,) entropy at the nearest surface sample; 1 beyond `unseen_m` of every sample."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if self._surface_tree is None:
            return np.ones(len(points))
        dist, nearest = self._surface_tree.query(points)
        entropy = np.where(dist <= self.config.unseen_m, self.entropy[nearest], 1.0)
        if self.config.boundary_m is None:
            return entropy
        return np.maximum(entropy, self.border(points))

    def border(self, points: np.ndarray) -> np.ndarray:
        """(N,) in [0, 1]: 1 where the nearest touches of two labels are equally far, 0
        where the nearest other label is `boundary_m` farther than the nearest touch (or
        the term is off, or fewer than two labels have been read)."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if len(self._label_trees) < 2:
            return np.zeros(len(points))
        per_label = np.stack([tree.query(points)[0] for tree in self._label_trees], axis=1)
        two = np.sort(per_label, axis=1)[:, :2]
        return np.clip(1.0 - (two[:, 1] - two[:, 0]) / self.config.boundary_m, 0.0, 1.0)

    def confirms(self, points: np.ndarray) -> np.ndarray:
        """(N,) 1.0 where a point lies within `confirm_m` of an unconfirmed reading, else 0."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if self._confirm_tree is None:
            return np.zeros(len(points))
        return (self._confirm_tree.query(points)[0] <= self.config.confirm_m).astype(np.float64)

    def score(self, points: np.ndarray) -> np.ndarray:
        """(N,) touch scores in [0, 1] of object-frame points: higher = touch there first."""
        c = self.config
        novelty = np.minimum(self.touch_distance(points) / c.novelty_m, 1.0)
        total = c.uncertainty_weight * self.uncertainty(points) + c.novelty_weight * novelty
        base = total / (c.uncertainty_weight + c.novelty_weight)
        if c.confirm_weight == 0:
            return base
        return base + c.confirm_weight * self.confirms(points) * (1.0 - base)

    def suggestions(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The k best surface samples, at least novelty_m / 2 apart: (k', 3) points, (k',) scores."""
        if not len(self.surface):
            return np.zeros((0, 3)), np.zeros(0)
        scores = self.score(self.surface)
        order = np.lexsort((np.arange(len(scores)), -scores))  # best first, ties by index
        chosen: list[int] = []
        for i in order:
            p = self.surface[i]
            if all(
                np.linalg.norm(p - self.surface[j]) >= 0.5 * self.config.novelty_m for j in chosen
            ):
                chosen.append(int(i))
                if len(chosen) == k:
                    break
        return self.surface[chosen], scores[chosen]

    def hotspot(self) -> np.ndarray | None:
        """The surface sample most worth touching: best score, then farthest from any touch."""
        if not len(self.surface):
            return None
        scores = self.score(self.surface)
        far = np.minimum(self.touch_distance(self.surface), 1.0)  # finite before any touch
        return self.surface[int(np.lexsort((-far, -scores))[0])]


def _label_trees(touched: np.ndarray, labels: np.ndarray | None) -> list[cKDTree]:
    """A KD-tree of the touches read as each label (labels read at least once)."""
    if labels is None:
        return []
    labels = np.asarray(labels).reshape(-1)
    if len(labels) != len(touched):
        raise ValueError(f"{len(touched)} touches but {len(labels)} labels")
    return [cKDTree(touched[labels == c]) for c in np.unique(labels[labels >= 0])]
