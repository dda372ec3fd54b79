"""What the mapper remembers: camera keyframes (windowed) and every touch (replayed).

Camera frames are many and redundant, so training uses a window: the most recent
keyframes plus older ones drawn with probability proportional to their last loss (the
frames the field explains worst, as in iSDF). Touches are sparse and carry the material
labels, so every touch is kept and replayed for the whole run.

All points are stored in the object frame, as float32 tensors on the mapper's device.
"""

from __future__ import annotations

import torch


def _check_points(points: torch.Tensor, name: str) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {tuple(points.shape)}")


class KeyframeBuffer:
    """Camera keyframes: object-frame surface points and the camera centre of each."""

    def __init__(self, max_keyframes: int, window_recent: int, window_by_loss: int) -> None:
        if max_keyframes < 1 or window_recent < 1 or window_by_loss < 0:
            raise ValueError(
                f"need max_keyframes >= 1, window_recent >= 1, window_by_loss >= 0; got "
                f"{max_keyframes}, {window_recent}, {window_by_loss}"
            )
        self.max_keyframes = max_keyframes
        self.window_recent = window_recent
        self.window_by_loss = window_by_loss
        self.points: list[torch.Tensor] = []
        self.origins: list[torch.Tensor] = []  # (3,) camera centre per keyframe
        self.frame_indices: list[int] = []
        self.losses: list[float] = []

    def __len__(self) -> int:
        return len(self.points)

    @property
    def num_points(self) -> int:
        return sum(int(p.shape[0]) for p in self.points)

    def add(self, points: torch.Tensor, origin: torch.Tensor, frame_index: int) -> None:
        _check_points(points, "keyframe points")
        if origin.shape != (3,):
            raise ValueError(f"keyframe origin must have shape (3,), got {tuple(origin.shape)}")
        if points.shape[0] == 0:
            return
        # New keyframes start with the highest known loss so they are drawn soon.
        self.points.append(points)
        self.origins.append(origin)
        self.frame_indices.append(int(frame_index))
        self.losses.append(max(self.losses, default=1.0))
        if len(self.points) > self.max_keyframes:
            self._evict()

    def _evict(self) -> None:
        """Drop the best-explained keyframe outside the recent window."""
        old = range(len(self.points) - self.window_recent)
        drop = min(old, key=lambda i: self.losses[i])
        for store in (self.points, self.origins, self.frame_indices, self.losses):
            del store[drop]

    def window(self, generator: torch.Generator) -> list[int]:
        """Indices of the keyframes to train on: recent ones plus older ones drawn by loss."""
        n = len(self.points)
        recent = list(range(max(0, n - self.window_recent), n))
        n_old = n - len(recent)
        if n_old == 0 or self.window_by_loss == 0:
            return recent
        weights = torch.tensor(self.losses[:n_old], dtype=torch.float64).clamp_min(1e-12)
        k = min(self.window_by_loss, n_old)
        chosen = torch.multinomial(weights, k, replacement=False, generator=generator)
        return sorted(int(i) for i in chosen) + recent

    def update_losses(self, keyframe_ids: list[int], losses: list[float]) -> None:
        for i, loss in zip(keyframe_ids, losses):
            self.losses[i] = float(loss)

    def state_dict(self) -> dict:
        return {
            "points": list(self.points),
            "origins": list(self.origins),
            "frame_indices": list(self.frame_indices),
            "losses": list(self.losses),
        }

    def load_state_dict(self, state: dict, device: torch.device) -> None:
        self.points = [p.to(device) for p in state["points"]]
        self.origins = [o.to(device) for o in state["origins"]]
        self.frame_indices = [int(i) for i in state["frame_indices"]]
        self.losses = [float(v) for v in state["losses"]]


def _neighbour_counts(
    distances: torch.Tensor, labels: torch.Tensor, radius: float, events: torch.Tensor | None
) -> tuple[torch.Tensor, torch.Tensor]:
    """(T,) other touches (presses, with `events`) within `radius`, and those that agree.

    `distances` (T, T) between the touches' centroids.
    """
    near = distances < radius
    near.fill_diagonal_(False)
    agreeing = near & (labels[None, :] == labels[:, None])
    if events is None:
        return near.sum(1), agreeing.sum(1)
    near &= events[None, :] != events[:, None]
    agreeing &= near
    # (T, K) one-hot press membership: count the presses a touch sees, not their frames.
    _, press = torch.unique(events, return_inverse=True)
    members = torch.nn.functional.one_hot(press).to(distances.dtype)
    neighbours = ((near.to(distances.dtype) @ members) > 0).sum(1)
    return neighbours, ((agreeing.to(distances.dtype) @ members) > 0).sum(1)


def outvoted_touches(
    centroids: torch.Tensor,
    labels: torch.Tensor,
    radius: float,
    min_neighbours: int,
    min_agreement: float,
    min_support: int = 0,
    events: torch.Tensor | None = None,
    support_radius: float | None = None,
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
    distances = torch.cdist(centroids, centroids)
    neighbours, agree = _neighbour_counts(distances, labels, radius, events)
    outvoted = (neighbours >= min_neighbours) & (agree < min_agreement * neighbours)
    if min_support > 0:
        if support_radius is not None and support_radius != radius:
            _, agree = _neighbour_counts(distances, labels, support_radius, events)
        outvoted |= agree < min_support
    return outvoted


def press_events(fingers: list[str | None], frames: list[int], gap: int) -> torch.Tensor:
    """(T,) press ids: a finger's touches at most `gap` frames after its previous one share it.

    Touches must come in frame order. A touch without a finger (None) is a press of its
    own, as is every touch when `gap` < 1.
    """
    if len(fingers) != len(frames):
        raise ValueError(f"{len(fingers)} fingers for {len(frames)} frame indices")
    ids, last = [], {}
    for finger, frame in zip(fingers, frames):
        previous = last.get(finger)
        if (
            finger is not None
            and gap >= 1
            and previous is not None
            and 0 <= frame - previous[0] <= gap
        ):
            ids.append(previous[1])
        else:
            ids.append(len(ids))
        last[finger] = (frame, ids[-1])
    return torch.tensor(ids, dtype=torch.long)


class TouchBuffer:
    """Every touch: a fixed number of contact points each, the sensor axis, label and weight.

    Each touch stores exactly `points_per_touch` points (drawn with replacement when the
    contact patch has fewer pixels), so uniform sampling over points is uniform over touches.
    """

    def __init__(
        self,
        device: torch.device,
        vote_radius: float = 0.0,
        vote_min_neighbours: int = 3,
        vote_min_agreement: float = 0.25,
        vote_min_support: int = 0,
        vote_press_gap: int = 0,
        vote_support_radius: float | None = None,
    ) -> None:
        self.device = device
        self.vote_radius = float(vote_radius)
        self.vote_min_neighbours = int(vote_min_neighbours)
        self.vote_min_agreement = float(vote_min_agreement)
        self.vote_min_support = int(vote_min_support)
        self.vote_press_gap = int(vote_press_gap)  # 0: every touch votes on its own
        self.vote_support_radius = (
            None if vote_support_radius is None else float(vote_support_radius)
        )
        self._num_outvoted = 0  # set with the cached tensors; read through num_outvoted
        self._points: list[torch.Tensor] = []
        self._axes: list[torch.Tensor] = []
        self._labels: list[torch.Tensor] = []
        self._weights: list[torch.Tensor] = []
        self._fingers: list[str | None] = []  # which finger made each touch (None: unknown)
        self._frames: list[int] = []  # frame index of each touch
        self._cat: dict[str, torch.Tensor] | None = None
        self.num_touches = 0
        self.num_labelled = 0

    def add(
        self,
        points: torch.Tensor,
        axis: torch.Tensor,
        label: int,
        weight: float,
        finger: str | None = None,
        frame_index: int = -1,
    ) -> None:
        """`label` -1 keeps the touch for geometry only; `finger` and `frame_index` tell
        the vote which touches are frames of one press (None: a press of its own)."""
        _check_points(points, "touch points")
        n = points.shape[0]
        self._fingers.append(finger)
        self._frames.append(int(frame_index))
        self._points.append(points)
        self._axes.append(axis.reshape(1, 3).expand(n, 3).clone())
        self._labels.append(torch.full((n,), int(label), dtype=torch.long, device=points.device))
        self._weights.append(
            torch.full((n,), float(weight), dtype=torch.float32, device=points.device)
        )
        self.num_touches += 1
        self.num_labelled += int(label >= 0)
        self._cat = None

    def tensors(self) -> dict[str, torch.Tensor]:
        """All touches concatenated: points, axes, labels, weights, and the labelled subset."""
        if self._cat is None:
            if self._points:
                cat = {
                    "points": torch.cat(self._points),
                    "axes": torch.cat(self._axes),
                    "labels": torch.cat(self._labels),
                    "weights": torch.cat(self._weights),
                }
            else:
                empty3 = torch.zeros(0, 3, device=self.device)
                cat = {
                    "points": empty3,
                    "axes": empty3,
                    "labels": torch.zeros(0, dtype=torch.long, device=self.device),
                    "weights": torch.zeros(0, device=self.device),
                }
            labelled = cat["labels"] >= 0
            self._num_outvoted = 0
            if self.vote_radius > 0.0 and self.num_labelled > 0:
                labelled = labelled & ~self._outvoted_points()
            cat["labelled_points"] = cat["points"][labelled]
            cat["labelled_labels"] = cat["labels"][labelled]
            cat["labelled_weights"] = cat["weights"][labelled]
            self._cat = cat
        return self._cat

    def _outvoted_points(self) -> torch.Tensor:
        """Per stored point: does its touch get outvoted by its labelled neighbours?"""
        labels = torch.stack([t[0] for t in self._labels])
        centroids = torch.stack([p.mean(0) for p in self._points])
        mine = labels >= 0
        kept = torch.nonzero(mine).flatten().tolist()
        events = press_events(
            [self._fingers[i] for i in kept], [self._frames[i] for i in kept], self.vote_press_gap
        ).to(labels.device)
        outvoted = torch.zeros(len(labels), dtype=torch.bool, device=labels.device)
        outvoted[mine] = outvoted_touches(
            centroids[mine],
            labels[mine],
            self.vote_radius,
            self.vote_min_neighbours,
            self.vote_min_agreement,
            self.vote_min_support,
            events,
            self.vote_support_radius,
        )
        self._num_outvoted = int(outvoted.sum())
        sizes = torch.tensor([len(p) for p in self._points], device=labels.device)
        return torch.repeat_interleave(outvoted, sizes)

    @property
    def num_outvoted(self) -> int:
        """Labelled touches left out of the material loss by the vote, as of the latest touch."""
        self.tensors()
        return self._num_outvoted

    @property
    def num_points(self) -> int:
        return sum(int(p.shape[0]) for p in self._points)

    def state_dict(self) -> dict:
        return {
            "points": list(self._points),
            "axes": list(self._axes),
            "labels": list(self._labels),
            "weights": list(self._weights),
            "fingers": list(self._fingers),
            "frames": list(self._frames),
            "num_touches": self.num_touches,
            "num_labelled": self.num_labelled,
        }

    def load_state_dict(self, state: dict) -> None:
        self._points = [t.to(self.device) for t in state["points"]]
        self._axes = [t.to(self.device) for t in state["axes"]]
        self._labels = [t.to(self.device) for t in state["labels"]]
        self._weights = [t.to(self.device) for t in state["weights"]]
        # Checkpoints from before presses were recorded: every touch a press of its own.
        self._fingers = list(state.get("fingers", [None] * len(self._points)))
        self._frames = [int(f) for f in state.get("frames", [-1] * len(self._points))]
        self.num_touches = int(state["num_touches"])
        self.num_labelled = int(state["num_labelled"])
        self._cat = None
