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


def outvoted_touches(
    centroids: torch.Tensor,
    labels: torch.Tensor,
    radius: float,
    min_neighbours: int,
    min_agreement: float,
    min_support: int = 0,
) -> torch.Tensor:
    """(T,) bool: labelled touches that their labelled neighbours contradict or do not back.

    A touch is outvoted when at least `min_neighbours` other touches lie within `radius`
    (centroid distance) and fewer than `min_agreement` of them carry its label: one
    confident misclassification among many consistent touches would otherwise paint its
    own patch. A touch with few neighbours, e.g. on a small patch of another material
    with touches of its own, is kept, unless fewer than `min_support` of its neighbours
    carry its label: a lone wrong touch where nobody else touched paints the largest
    patch, while a real contact is usually labelled in several frames as it slides.
    """
    if centroids.ndim != 2 or centroids.shape[1] != 3 or labels.shape != centroids.shape[:1]:
        raise ValueError(
            f"expected (T, 3) centroids and (T,) labels, got {centroids.shape}, {labels.shape}"
        )
    if len(labels) == 0 or radius <= 0.0:
        return torch.zeros(len(labels), dtype=torch.bool, device=labels.device)
    near = torch.cdist(centroids, centroids) < radius
    near.fill_diagonal_(False)
    neighbours = near.sum(1)
    agree = (near & (labels[None, :] == labels[:, None])).sum(1)
    return ((neighbours >= min_neighbours) & (agree < min_agreement * neighbours)) | (
        agree < min_support
    )


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
    ) -> None:
        self.device = device
        self.vote_radius = float(vote_radius)
        self.vote_min_neighbours = int(vote_min_neighbours)
        self.vote_min_agreement = float(vote_min_agreement)
        self.vote_min_support = int(vote_min_support)
        self._num_outvoted = 0  # set with the cached tensors; read through num_outvoted
        self._points: list[torch.Tensor] = []
        self._axes: list[torch.Tensor] = []
        self._labels: list[torch.Tensor] = []
        self._weights: list[torch.Tensor] = []
        self._cat: dict[str, torch.Tensor] | None = None
        self.num_touches = 0
        self.num_labelled = 0

    def add(self, points: torch.Tensor, axis: torch.Tensor, label: int, weight: float) -> None:
        """`label` -1 keeps the touch for geometry only."""
        _check_points(points, "touch points")
        n = points.shape[0]
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
        outvoted = torch.zeros(len(labels), dtype=torch.bool, device=labels.device)
        outvoted[mine] = outvoted_touches(
            centroids[mine],
            labels[mine],
            self.vote_radius,
            self.vote_min_neighbours,
            self.vote_min_agreement,
            self.vote_min_support,
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
            "num_touches": self.num_touches,
            "num_labelled": self.num_labelled,
        }

    def load_state_dict(self, state: dict) -> None:
        self._points = [t.to(self.device) for t in state["points"]]
        self._axes = [t.to(self.device) for t in state["axes"]]
        self._labels = [t.to(self.device) for t in state["labels"]]
        self._weights = [t.to(self.device) for t in state["weights"]]
        self.num_touches = int(state["num_touches"])
        self.num_labelled = int(state["num_labelled"])
        self._cat = None
