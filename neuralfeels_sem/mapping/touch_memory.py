"""What the mapper remembers of touch: every touch, replayed for the whole run.

Touches are sparse and carry the material labels, so every touch is kept (object-frame
points, float32 on the mapper's device). Press fusion (press_fusion.py) labels touches the
classifier abstained on from the presses around them; the label vote (label_vote.py)
decides which labelled touches the material loss uses.
"""

from __future__ import annotations

import bisect

import torch

from neuralfeels_sem.mapping.keyframes import check_points
from neuralfeels_sem.mapping.label_vote import LabelVote, press_events
from neuralfeels_sem.mapping.press_fusion import PressFusion

# A material counts as read by a touch when at least this share of its labelled points
# name it: one stray patch at the rim of an imprint does not make the touch back it.
READ_SHARE = 0.1


def materials_read(labels: torch.Tensor) -> tuple[int, ...]:
    """The materials a touch's point labels name (-1: none), each on >= READ_SHARE of them."""
    read = labels[labels >= 0]
    if not len(read):
        return ()
    counts = torch.bincount(read)
    return tuple(int(c) for c in torch.nonzero(counts >= READ_SHARE * len(read)).flatten())


class TouchBuffer:
    """Every touch: a fixed number of contact points each, the sensor axis, label and weight.

    Each touch stores exactly `points_per_touch` points (drawn with replacement when the
    contact patch has fewer pixels), so uniform sampling over points is uniform over touches.
    """

    def __init__(
        self,
        device: torch.device,
        vote: LabelVote | None = None,
        fusion: PressFusion | None = None,
    ) -> None:
        """`vote`: which labelled touches to leave out of the material loss (None: none);
        `fusion`: how abstained touches are labelled from the presses around them (None: never)."""
        self.device = device
        self.vote = vote
        self.fusion = fusion
        self._num_outvoted = 0  # set with the cached tensors; read through num_outvoted
        self._points: list[torch.Tensor] = []
        self._axes: list[torch.Tensor] = []
        self._labels: list[torch.Tensor] = []
        self._weights: list[torch.Tensor] = []
        self._touch_labels: list[int] = []  # each touch's label for the vote (-1: none)
        # The vote's items, one per material a touch reads: touch, material, centroid.
        self._item_touch: list[int] = []
        self._item_label: list[int] = []
        self._item_centroid: list[torch.Tensor] = []
        self._centroids: list[torch.Tensor] = []  # each touch's point centroid: its place
        self._fingers: list[str | None] = []  # which finger made each touch (None: unknown)
        self._frames: list[int] = []  # frame index of each touch
        # The classifier's class probabilities of each touch ((C,); empty: none, e.g. no
        # contact) and whether it abstained for an imprint along the sensor's edge.
        self._probs: list[torch.Tensor] = []
        self._at_edge: list[bool] = []
        # Every frame the buffer was offered, ascending: presses are counted in these, so a
        # press keeps its frames together when realtime pacing maps every other frame.
        self._mapped: list[int] = []
        self._cat: dict[str, torch.Tensor] | None = None
        # The per-touch lists concatenated (`_joined`) are valid for the first `_joined_upto`
        # touches: a new touch appends, and only a changed touch re-joins from itself on.
        self._joined: dict[str, torch.Tensor] = {}
        self._joined_upto = 0
        self._starts: list[int] = [0]  # each touch's first row in the joined tensors
        self.num_touches = 0
        self.num_labelled = 0
        self.num_fused = 0  # of num_labelled: labelled by press fusion

    def note_frame(self, frame_index: int) -> None:
        """A frame was mapped (with or without touches): press gaps count mapped frames."""
        i = bisect.bisect_left(self._mapped, frame_index)
        if i < len(self._mapped) and self._mapped[i] == frame_index:
            return
        if i < len(self._mapped):
            self._cat = None  # an earlier frame: the ranks of later touches move
        self._mapped.insert(i, int(frame_index))

    @property
    def newest_frame(self) -> int:
        """The newest frame the buffer was offered (-1: none yet)."""
        return self._mapped[-1] if self._mapped else -1

    def _press_frames(self, touches: list[int]) -> list[int]:
        """The touches' frames as ranks among the mapped frames (frame indices offline,
        where every frame is mapped; consecutive at realtime pacing, where frames skip)."""
        return [bisect.bisect_left(self._mapped, self._frames[t]) for t in touches]

    def add(
        self,
        points: torch.Tensor,
        axis: torch.Tensor,
        label: int | torch.Tensor,
        weight: float | torch.Tensor,
        finger: str | None = None,
        frame_index: int = -1,
        probs: torch.Tensor | None = None,
        at_edge: bool = False,
    ) -> None:
        """Store one touch. `label` -1 keeps it for geometry only; a (n,) tensor gives each
        point its own label (-1: none) and `weight` then is (n,) too (patch readings). The
        vote judges each material the touch reads on its own (`point_labels_used`).
        `finger` and `frame_index` tell the vote which touches are frames of one press (None:
        a press of its own). `probs` (C,): the classifier's reading, pooled by press fusion;
        `at_edge`: it abstained because the imprint lies along the sensor's edge."""
        check_points(points, "touch points")
        n = points.shape[0]
        device = points.device
        labels = torch.as_tensor(label, dtype=torch.long, device=device).expand(n).clone()
        weights = torch.as_tensor(weight, dtype=torch.float32, device=device).expand(n).clone()
        read = labels[labels >= 0]
        self._touch_labels.append(int(torch.mode(read).values) if len(read) else -1)
        self._add_items(len(self._points), points, labels)
        self._fingers.append(finger)
        self._frames.append(int(frame_index))
        self._probs.append(
            torch.zeros(0, device=device) if probs is None else probs.to(device, torch.float32)
        )
        self._at_edge.append(bool(at_edge))
        self.note_frame(frame_index)
        self._points.append(points)
        self._centroids.append(points.mean(0))
        self._starts.append(self._starts[-1] + n)
        self._axes.append(axis.reshape(1, 3).expand(n, 3).clone())
        self._labels.append(labels)
        self._weights.append(weights)
        self.num_touches += 1
        self.num_labelled += int(len(read) > 0)
        self._cat = None
        if probs is not None and self.fusion is not None and self.fusion.active:
            self._fuse()

    def _fuse(self) -> None:
        """Label the abstained touches that the presses around them now read surely enough.

        Only those within the fusion radius of the newest touch: nobody else's evidence
        changed."""
        fusion = self.fusion
        pooled = [
            t
            for t, p in enumerate(self._probs)
            if len(p) and (fusion.include_edge or not self._at_edge[t])
        ]
        if not pooled or pooled[-1] != len(self._probs) - 1:
            return  # the newest touch is not pooled
        centroids = torch.stack([self._points[t].mean(0) for t in pooled])
        near_new = (centroids - centroids[-1]).norm(dim=1) < fusion.radius
        open_ = [i for i, t in enumerate(pooled) if self._touch_labels[t] < 0 and near_new[i]]
        if not open_:
            return
        labels, probability = fusion.fuse(
            centroids,
            torch.stack([self._probs[t] for t in pooled]),
            self._press_ids(pooled, fusion.press_gap),
            torch.tensor(open_, device=self.device),
        )
        for i, label, p in zip(open_, labels.tolist(), probability.tolist()):
            if label >= 0:
                self._relabel(pooled[i], label, p * fusion.weight)

    def _relabel(self, touch: int, label: int, weight: float) -> None:
        """Give an unlabelled touch one label for all its points (press fusion)."""
        self._labels[touch] = torch.full_like(self._labels[touch], label)
        self._weights[touch] = torch.full_like(self._weights[touch], weight)
        self._touch_labels[touch] = label
        self._add_items(touch, self._points[touch], self._labels[touch])
        self.num_labelled += 1
        self.num_fused += 1
        self._joined_upto = min(self._joined_upto, touch)
        self._cat = None

    def tensors(self) -> dict[str, torch.Tensor]:
        """All touches concatenated: points, axes, labels, weights, and the labelled subset
        (with each labelled point's frame index)."""
        if self._cat is None:
            cat = dict(self._joined_lists())
            labelled = cat["labels"] >= 0
            frames = torch.tensor(self._frames, dtype=torch.long, device=labelled.device)
            self._num_outvoted = 0
            if self.vote is not None and self.vote.active and self.num_labelled > 0:
                labelled = labelled & ~self._outvoted_points()
            cat["labelled_points"] = cat["points"][labelled]
            cat["labelled_labels"] = cat["labels"][labelled]
            cat["labelled_weights"] = cat["weights"][labelled]
            cat["labelled_frames"] = frames[self._touch_of_point(labelled.device)][labelled]
            self._cat = cat
        return self._cat

    def _joined_lists(self) -> dict[str, torch.Tensor]:
        """Points, axes, labels and weights of every touch, each list as one tensor; only
        the touches past `_joined_upto` are joined anew (the same tensors as joining all)."""
        lists = {
            "points": self._points, "axes": self._axes,
            "labels": self._labels, "weights": self._weights,
        }  # fmt: skip
        if not self._points:
            empty3 = torch.zeros(0, 3, device=self.device)
            return {
                "points": empty3,
                "axes": empty3,
                "labels": torch.zeros(0, dtype=torch.long, device=self.device),
                "weights": torch.zeros(0, device=self.device),
            }
        upto, row = self._joined_upto, self._starts[self._joined_upto]
        if upto < len(self._points):
            self._joined = {
                key: torch.cat(([self._joined[key][:row]] if upto else []) + items[upto:])
                for key, items in lists.items()
            }
            self._joined_upto = len(self._points)
        return self._joined

    def move_frame(self, frame_index: int, rotation: torch.Tensor, shift: torch.Tensor) -> int:
        """Re-place the touches of one frame (x -> rotation x + shift, object frame: its
        pose was refined; axes turn with it, the vote's centroids follow); how many."""
        moved = [t for t, index in enumerate(self._frames) if index == frame_index]
        for t in moved:
            self._points[t] = self._points[t] @ rotation.T + shift
            self._centroids[t] = self._points[t].mean(0)
            self._axes[t] = self._axes[t] @ rotation.T
        for item, touch in enumerate(self._item_touch):
            if touch in moved:
                self._item_centroid[item] = rotation @ self._item_centroid[item] + shift
        if moved:
            self._joined_upto = min(self._joined_upto, moved[0])
            self._cat = None
        return len(moved)

    def _outvoted_points(self) -> torch.Tensor:
        """Per stored point: is its label left out (its touch's reading of that material
        outvoted, or named by too few of the touch's points to count as read)?"""
        labels = self._joined_lists()["labels"]
        used, self._num_outvoted = self._used_flat(labels, self._touch_of_point(labels.device))
        return (labels >= 0) & (used < 0)

    def _used_flat(
        self, labels: torch.Tensor, touch_of_point: torch.Tensor
    ) -> tuple[torch.Tensor, int]:
        """All touches' point labels (`labels`, concatenated; `touch_of_point` their touch
        indices) with -1 where left out, and how many items the vote left out."""
        if not self._item_touch:
            return torch.full_like(labels, -1), 0
        classes = int(max(labels.max().item(), max(self._item_label))) + 1
        item_touch = torch.tensor(self._item_touch, device=labels.device)
        item_label = torch.tensor(self._item_label, device=labels.device)
        dropped = self._items_dropped(item_touch, item_label)
        # (touch, material) -> is that reading kept; unread materials stay False.
        keep = torch.zeros(len(self._labels) * classes, dtype=torch.bool, device=labels.device)
        keep[item_touch * classes + item_label] = ~dropped
        ok = keep[touch_of_point * classes + labels.clamp_min(0)] & (labels >= 0)
        return torch.where(ok, labels, -1), int(dropped.sum())

    def _press_ids(self, touches: list[int], gap: int) -> torch.Tensor:
        """(len(touches),) press ids of these touches (in frame order), presses chained
        over them alone (label_vote.press_events)."""
        fingers = [self._fingers[t] for t in touches]
        reach = None if self.vote is None else self.vote.press_reach
        where = None if reach is None else self._places(touches)
        events = press_events(fingers, self._press_frames(touches), gap, where, reach)
        return events.to(self.device)

    def _touch_of_point(self, device: torch.device) -> torch.Tensor:
        """The touch index of every stored point, in storage order."""
        sizes = torch.tensor(self._starts, device=device).diff()  # each touch's point count
        return torch.repeat_interleave(torch.arange(len(sizes), device=device), sizes)

    def _items_dropped(self, item_touch: torch.Tensor, item_label: torch.Tensor) -> torch.Tensor:
        """(I,) bool: items (one material a touch reads) the vote leaves out."""
        if self.vote is None or not self.vote.active:
            return torch.zeros(len(item_touch), dtype=torch.bool, device=item_touch.device)
        # Presses are chained over labelled touches only: a geometry-only touch between two
        # frames of a finger must not join presses the vote would count apart.
        labelled, touch = torch.unique(item_touch, return_inverse=True)
        fingers = [self._fingers[t] for t in labelled.tolist()]
        frames = self._press_frames(labelled.tolist())
        centroids = torch.stack(self._item_centroid).to(item_touch.device)
        places = None if self.vote.press_reach is None else self._places(labelled.tolist())
        return self.vote.outvoted(centroids, item_label, fingers, frames, touch, places)

    def _places(self, touches: list[int]) -> torch.Tensor:
        """(len(touches), 3) the touches' point centroids (for the vote's press reach)."""
        if not touches:
            return torch.zeros(0, 3, device=self.device)
        return torch.stack([self._centroids[t] for t in touches])

    def point_labels_used(self) -> list[torch.Tensor]:
        """Per touch, its point labels with -1 where the material loss leaves them out.

        The vote runs over items, each one material a touch reads (`materials_read`), at
        the centroid of the points that read it: a plain touch is one item, as before patch
        readings; a touch across a border is one item per side, each judged on its own."""
        if not self._labels:
            return []
        labels = self._joined_lists()["labels"]
        used, _ = self._used_flat(labels, self._touch_of_point(labels.device))
        return list(torch.split(used, [len(lab) for lab in self._labels]))

    def unconfirmed_readings(self, radius: float) -> torch.Tensor:
        """(K, 3) centroids of readings the vote leaves out that no reading of another
        press lies within `radius` of: a lone reading a second press would confirm or
        refute (a small part read once looks like this, and so does a misreading)."""
        if not self._item_touch or self.vote is None or not self.vote.active:
            return torch.zeros(0, 3, device=self.device)
        item_touch = torch.tensor(self._item_touch, device=self.device)
        dropped = self._items_dropped(
            item_touch, torch.tensor(self._item_label, device=self.device)
        )
        labelled, touch = torch.unique(item_touch, return_inverse=True)
        events = self._press_ids(labelled.tolist(), self.vote.press_gap)[touch]
        centroids = torch.stack(self._item_centroid).to(self.device)
        near = torch.cdist(centroids[dropped], centroids) < radius
        near &= events[dropped][:, None] != events[None, :]
        return centroids[dropped][~near.any(1)]

    def outvoted(self) -> torch.Tensor:
        """(T,) bool: labelled touches the vote leaves out entirely (all False without one)."""
        if not self._labels:
            return torch.zeros(0, dtype=torch.bool, device=self.device)
        labels = torch.cat(self._labels)
        touch_of_point = self._touch_of_point(labels.device)
        used, _ = self._used_flat(labels, touch_of_point)
        read = torch.zeros(len(self._labels), device=labels.device).index_add_(
            0, touch_of_point, (labels >= 0).float()
        )
        kept = torch.zeros(len(self._labels), device=labels.device).index_add_(
            0, touch_of_point, (used >= 0).float()
        )
        return (read > 0) & (kept == 0)

    def _add_items(self, touch: int, points: torch.Tensor, labels: torch.Tensor) -> None:
        """Record the materials a touch reads and the centroid of the points reading each."""
        for material in materials_read(labels):
            self._item_touch.append(touch)
            self._item_label.append(material)
            self._item_centroid.append(points[labels == material].mean(0))

    @property
    def num_outvoted(self) -> int:
        """Labelled touches left out of the material loss by the vote, as of the latest touch."""
        self.tensors()
        return self._num_outvoted

    def state_dict(self) -> dict:
        return {
            "points": list(self._points),
            "axes": list(self._axes),
            "labels": list(self._labels),
            "touch_labels": list(self._touch_labels),
            "weights": list(self._weights),
            "fingers": list(self._fingers),
            "frames": list(self._frames),
            "mapped_frames": list(self._mapped),
            "probs": list(self._probs),
            "at_edge": list(self._at_edge),
            "num_touches": self.num_touches,
            "num_labelled": self.num_labelled,
            "num_fused": self.num_fused,
        }

    def load_state_dict(self, state: dict) -> None:
        self._points = [t.to(self.device) for t in state["points"]]
        self._axes = [t.to(self.device) for t in state["axes"]]
        self._labels = [t.to(self.device) for t in state["labels"]]
        self._weights = [t.to(self.device) for t in state["weights"]]
        # Checkpoints from before patch readings: a touch's label is its points' one label.
        self._touch_labels = [
            int(t) for t in state.get("touch_labels", [int(p[0]) for p in self._labels])
        ]
        self._item_touch, self._item_label, self._item_centroid = [], [], []
        for touch, (points, labels) in enumerate(zip(self._points, self._labels)):
            self._add_items(touch, points, labels)
        # Checkpoints from before presses were recorded: every touch a press of its own.
        self._fingers = list(state.get("fingers", [None] * len(self._points)))
        self._frames = [int(f) for f in state.get("frames", [-1] * len(self._points))]
        # Checkpoints from before mapped frames were recorded: the frames touches came in.
        self._mapped = [int(f) for f in state.get("mapped_frames", sorted(set(self._frames)))]
        # Checkpoints from before press fusion: no touch has probabilities.
        empty = torch.zeros(0, device=self.device)
        self._probs = [t.to(self.device) for t in state.get("probs", [empty] * len(self._points))]
        self._at_edge = [bool(e) for e in state.get("at_edge", [False] * len(self._points))]
        self.num_touches = int(state["num_touches"])
        self.num_labelled = int(state["num_labelled"])
        self.num_fused = int(state.get("num_fused", 0))
        self._centroids = [points.mean(0) for points in self._points]
        self._starts = [0]
        for points in self._points:
            self._starts.append(self._starts[-1] + len(points))
        self._joined_upto = 0
        self._cat = None
