"""The label vote: which labelled touches the material loss leaves out.

One confident misclassification among many consistent touches would otherwise paint its
own patch of the map. The settings are MapperConfig's `label_vote_*` (mapping/mapper.py);
`LabelVote.from_config` gathers them, and TouchBuffer applies the vote to its touches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch
from scipy.spatial import cKDTree

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig


@dataclass(frozen=True)
class LabelVote:
    """The vote's settings (no defaults here: they are MapperConfig's; see outvoted_touches).

    radius 0 switches the vote off; support_radius None means `radius`; press_gap 0 makes
    every touch a press of its own; steady_frames 0 lets no press back itself; press_reach
    None chains a finger's touches into one press however far it slides (see press_events).
    """

    radius: float
    min_neighbours: int
    min_agreement: float
    min_support: int
    press_gap: int
    support_radius: float | None
    steady_frames: int
    press_reach: float | None

    def __post_init__(self) -> None:
        if self.press_reach is not None and self.press_reach <= 0:
            raise ValueError(
                f"mapping.mapper.label_vote_press_reach={self.press_reach} must be > 0 "
                "(or null: presses by time alone)"
            )

    @classmethod
    def from_config(cls, config: MapperConfig) -> LabelVote:
        return cls(
            radius=float(config.label_vote_radius),
            min_neighbours=int(config.label_vote_min_neighbours),
            min_agreement=float(config.label_vote_min_agreement),
            min_support=int(config.label_vote_min_support),
            press_gap=int(config.label_vote_press_gap),
            support_radius=(
                None
                if config.label_vote_support_radius is None
                else float(config.label_vote_support_radius)
            ),
            steady_frames=int(config.label_vote_steady_frames),
            press_reach=(
                None
                if config.label_vote_press_reach is None
                else float(config.label_vote_press_reach)
            ),
        )

    @property
    def active(self) -> bool:
        return self.radius > 0.0

    def outvoted(
        self,
        centroids: torch.Tensor,
        labels: torch.Tensor,
        fingers: list[str | None],
        frames: list[int],
        touch_of: torch.Tensor | None = None,
        touch_centroids: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """(T,) bool over labelled touches (centroids (T, 3), labels (T,), in frame order;
        `frames` numbers the frames the mapper took, see TouchBuffer.note_frame).

        With `touch_of` the vote is over items, each one material a touch read (patch
        readings): (I,) centroids and labels of the items and the touch of each; `fingers`
        and `frames` stay per touch, and the items of one touch are one press.
        `touch_centroids` (touches, 3): where each touch is, for `press_reach` (needed with
        `touch_of`; without it the centroids are the touches').
        """
        where = centroids if touch_centroids is None and touch_of is None else touch_centroids
        events = press_events(fingers, frames, self.press_gap, where, self.press_reach)
        events = events.to(labels.device)
        frames_per_press = torch.bincount(events)
        if touch_of is not None:
            events = events[touch_of.to(labels.device)]
        steady = steady_presses(events, labels, frames_per_press, self.steady_frames)
        return outvoted_touches(
            centroids,
            labels,
            self.radius,
            self.min_neighbours,
            self.min_agreement,
            self.min_support,
            events,
            self.support_radius,
            steady,
        )


def steady_presses(
    events: torch.Tensor, labels: torch.Tensor, frames_per_press: torch.Tensor, min_frames: int
) -> torch.Tensor | None:
    """(T,) bool: items whose label their own press names steadily (None: `min_frames` 0).

    Steady: at least `min_frames` labelled frames of the press name the item's label, and
    they are at least half of the press's labelled frames (`frames_per_press`, indexed by
    press id). In the touch logs of 25 default runs (shipped and generated development
    objects), labels read steadily over three frames or more were wrong in 0.6 % of frames,
    labels a press read in one or two frames in 21 %: a steady press on a part nobody else
    touched is evidence enough, a brief one is not.
    """
    if min_frames <= 0 or len(labels) == 0:
        return None
    key = events * (int(labels.max()) + 1) + labels  # one id per (press, label)
    _, group, counts = torch.unique(key, return_inverse=True, return_counts=True)
    naming = counts[group]
    return (naming >= min_frames) & (2 * naming >= frames_per_press[events])


def _presses_near(
    points: np.ndarray, labels: np.ndarray, press: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """(T,) per touch: the other presses with a touch within `radius` of it, and those with
    a touch of its label there (points (T, 3), press (T,) ids from 0).

    Only the pairs within the radius are visited (a KD-tree): the vote runs after every
    frame over every touch so far, and a dense (T, T) count grew with the square of a run's
    length (about 0.1 s a frame at 3000 touches, 100 s of a default run)."""
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    close = (press[i] != press[j]) & (np.linalg.norm(points[i] - points[j], axis=1) < radius)
    i, j = i[close], j[close]
    same = labels[i] == labels[j]
    return _count_presses(i, j, press, len(labels)), _count_presses(
        i[same], j[same], press, len(labels)
    )


# Touches x presses up to this many cells are counted in a boolean table (a cell per pair
# of touch and press: no sort); larger runs sort the pairs instead.
TABLE_CELLS = 50_000_000


def _count_presses(i: np.ndarray, j: np.ndarray, press: np.ndarray, n: int) -> np.ndarray:
    """(n,) how many distinct presses the partners j of each touch i belong to."""
    width = int(press.max()) + 1 if len(press) else 1
    key = i * width + press[j]  # one entry per (touch, partner's press), repeated
    if n * width <= TABLE_CELLS:
        table = np.zeros(n * width, dtype=bool)
        table[key] = True
        return table.reshape(n, width).sum(axis=1)
    return np.bincount(np.unique(key) // width, minlength=n)


def _supported(
    points: np.ndarray, labels: np.ndarray, press: np.ndarray, radius: float, min_support: int
) -> np.ndarray:
    """(T,) bool: at least `min_support` other presses have a touch of the touch's label
    within `radius`. For one, each label's touches ask only for their k nearest of that
    label, k one more than any press holds of it: a touch of another press within the
    radius is then among them (a wide support radius holds most of a small object)."""
    if min_support > 1:
        return _presses_near(points, labels, press, radius)[1] >= min_support
    out = np.zeros(len(labels), dtype=bool)
    for label in np.unique(labels):
        idx = np.flatnonzero(labels == label)
        k = min(int(np.bincount(press[idx]).max()) + 1, len(idx))
        if k < 2:
            continue
        bound = np.nextafter(radius, np.inf)  # the test below is strict, as the count's
        dist, near = cKDTree(points[idx]).query(points[idx], k=k, distance_upper_bound=bound)
        found = near < len(idx)
        other = press[idx][np.where(found, near, 0)] != press[idx][:, None]
        out[idx] = (found & (dist < radius) & other).any(axis=1)
    return out


def outvoted_touches(
    centroids: torch.Tensor,
    labels: torch.Tensor,
    radius: float,
    min_neighbours: int,
    min_agreement: float,
    min_support: int = 0,
    events: torch.Tensor | None = None,
    support_radius: float | None = None,
    steady: torch.Tensor | None = None,
) -> torch.Tensor:
    """(T,) bool: labelled touches that their labelled neighbours contradict or do not back.

    A touch is outvoted when at least `min_neighbours` other touches lie within `radius`
    (centroid distance) and fewer than `min_agreement` of them carry its label: one
    confident misclassification among many consistent touches would otherwise paint its
    own patch. A touch with few neighbours, e.g. on a small patch of another material
    with touches of its own, is kept, unless fewer than `min_support` touches within
    `support_radius` (default `radius`) carry its label: a lone wrong touch where nobody
    else touched paints the largest patch.

    `events` (T,) groups touches into presses (see `press_events`): neighbours and
    agreeing neighbours are then counted as other presses, not frames. The frames of one
    press repeat one imprint, and a misclassified imprint is usually misclassified in all
    of them, so they must not back each other. None: every touch is its own press.
    """
    if centroids.ndim != 2 or centroids.shape[1] != 3 or labels.shape != centroids.shape[:1]:
        raise ValueError(
            f"expected (T, 3) centroids and (T,) labels, got {centroids.shape}, {labels.shape}"
        )
    if len(labels) == 0 or radius <= 0.0:
        return torch.zeros(len(labels), dtype=torch.bool, device=labels.device)
    if events is not None and events.shape != labels.shape:
        raise ValueError(f"expected (T,) events for {len(labels)} touches, got {events.shape}")
    points = centroids.detach().double().cpu().numpy()
    ids = np.arange(len(labels)) if events is None else events.cpu().numpy()
    press = np.unique(ids, return_inverse=True)[1].reshape(-1)
    label = labels.cpu().numpy()
    neighbours, agree = _presses_near(points, label, press, radius)
    # In float32, as torch compared them: the share is not always exact in binary.
    outvoted = (neighbours >= min_neighbours) & (
        agree < np.float32(min_agreement) * neighbours.astype(np.float32)
    )
    if min_support > 0:
        support = radius if support_radius is None else support_radius
        unsupported = ~_supported(points, label, press, support, min_support)
        outvoted |= unsupported if steady is None else unsupported & ~steady.cpu().numpy()
    return torch.from_numpy(outvoted).to(labels.device)


def press_events(
    fingers: list[str | None],
    frames: list[int],
    gap: int,
    centroids: torch.Tensor | None = None,
    reach: float | None = None,
) -> torch.Tensor:
    """(T,) press ids: a finger's touches at most `gap` frames after its previous one share
    it, while within `reach` of the press's first touch (`centroids` (T, 3); None: any).

    A press stands for one imprint read over several frames. A finger that slides on
    (the object turns under it; at realtime pacing the frames mapped lie further apart)
    reaches other places, and the press ends there: one material read across a border
    would otherwise be a minority of the long press and never steady (steady_presses).
    Touches must come in frame order. A touch without a finger (None) is a press of its
    own, as is every touch when `gap` < 1.
    """
    if len(fingers) != len(frames):
        raise ValueError(f"{len(fingers)} fingers for {len(frames)} frame indices")
    if reach is not None and (centroids is None or len(centroids) != len(fingers)):
        raise ValueError(f"press reach needs one centroid per touch ({len(fingers)})")
    where = None if reach is None else centroids.detach().double().cpu().numpy()
    ids, last = [], {}
    for t, (finger, frame) in enumerate(zip(fingers, frames)):
        previous = last.get(finger)
        chained = (
            finger is not None
            and gap >= 1
            and previous is not None
            and 0 <= frame - previous[0] <= gap
            and (where is None or _within(where[t], where[previous[2]], reach))
        )
        start = previous[2] if chained else t
        ids.append(previous[1] if chained else len(ids))
        last[finger] = (frame, ids[-1], start)
    return torch.tensor(ids, dtype=torch.long)


def _within(a, b, reach: float) -> bool:
    d = a - b
    return float(d @ d) <= reach * reach
