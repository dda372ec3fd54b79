"""What backs the map's material where no touch has been (mapping.mapper.fill_m).

The material branch learns from labelled touch points. Near them it reads what they said;
far from every one it only extrapolates, smoothly, and early in a run that extrapolation
favours whatever most touches named, so a material pressed a few times stays a few small
spots in a sea of the common one until the presses crowd round it. A map that gave each
point the label of its nearest press would be right sooner (bench.map_lag's readings map
leads the field by seconds on the shipped objects).

`MaterialSupport` holds the labelled points the field was trained on (thinned to one per
`VOXEL_M` cell, the label most of its points name). Where a query point x lies farther
than `fill_m` from all of them, at distance d from the nearest, the readout is that
point's label with a confidence that fades with the distance:

  p'(x) = s * onehot(label of the nearest trained point) + (1 - s) / C,
  s = exp(-(d - fill_m) / FADE_M)

so a boundary between two materials falls halfway between their presses, not wherever the
extrapolation put it, and the uncertainty (the entropy of p') grows with the distance from
the last press: the parts no press has settled stay flagged. Within fill_m the field reads
as it learned. Training never sees this: the loss uses the material branch's own logits.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree
from torch import Tensor

FADE_M = 0.02  # the fill's confidence falls by a factor e every this far past fill_m
VOXEL_M = 0.003  # the trained points are thinned to one per cell of this size
CELL_OFFSET = 1 << 20  # cell indices shifted to be non-negative (to +-3 km at 3 mm cells)
CELL_SPAN = 1 << 21  # and packed three to an int64 key


class MaterialSupport:
    """The labelled points the material branch was trained on, as a nearest-label fill.

    Args:
        points: (P, 3) trained points, metres in the field's frame (the touch memory's).
        labels: (P,) their class indices in [0, num_classes).
        num_classes: classes of the field.
        fill_m: beyond this distance from every trained point the fill applies.
    """

    def __init__(self, points: Tensor, labels: Tensor, num_classes: int, fill_m: float) -> None:
        if len(points) != len(labels):
            raise ValueError(f"{len(points)} support points but {len(labels)} labels")
        if fill_m <= 0:
            raise ValueError(f"fill_m={fill_m} must be > 0")
        # The touch memory's tensors themselves: a new support is made only when they change,
        # and the thinning and search tree wait for the first read (not every frame is read).
        self.source = (points, labels)
        self.num_classes, self.fill_m = int(num_classes), float(fill_m)
        self._tree: cKDTree | None = None
        self.points, self.labels = np.zeros((0, 3)), np.zeros(0, np.int64)

    def _build(self) -> None:
        points = self.source[0].detach().cpu().numpy().astype(np.float64).reshape(-1, 3)
        labels = self.source[1].detach().cpu().numpy().astype(np.int64).reshape(-1)
        if len(labels) and (labels.min() < 0 or labels.max() >= self.num_classes):
            raise ValueError(f"support labels must be in [0, {self.num_classes})")
        self.points, self.labels = _thin(points, labels, self.num_classes)
        self._tree = cKDTree(self.points) if len(self.points) else None

    def blend(self, x: Tensor, probs: Tensor) -> Tensor:
        """(N, C) probabilities: the field's within fill_m of a trained point, the fill beyond."""
        if self._tree is None and len(self.source[1]):
            self._build()
        if self._tree is None or len(x) == 0:
            return probs
        dist, nearest = self._tree.query(x.detach().cpu().numpy().astype(np.float64))
        far = torch.as_tensor(dist > self.fill_m, device=probs.device)
        if not bool(far.any()):
            return probs
        labels = torch.as_tensor(self.labels[nearest], device=probs.device)
        onehot = torch.nn.functional.one_hot(labels, self.num_classes).to(probs.dtype)
        share = np.exp(-np.maximum(dist - self.fill_m, 0.0) / FADE_M)
        s = torch.as_tensor(share, dtype=probs.dtype, device=probs.device)[:, None]
        filled = s * onehot + (1.0 - s) / self.num_classes
        return torch.where(far[:, None], filled, probs)


def _thin(points: np.ndarray, labels: np.ndarray, num_classes: int) -> tuple:
    """One point per VOXEL_M cell (the mean of its points), labelled by most of them.

    Cells are keyed by one integer each (in the order of their (x, y, z) indices), so the
    grouping is a 1-D sort: the advice of an active run rebuilds this every frame."""
    if not len(points):
        return points, labels
    cells = np.floor(points / VOXEL_M).astype(np.int64) + CELL_OFFSET
    key = (cells[:, 0] * CELL_SPAN + cells[:, 1]) * CELL_SPAN + cells[:, 2]
    _, cell, counts = np.unique(key, return_inverse=True, return_counts=True)
    cell = cell.reshape(-1)
    n = len(counts)
    centre = np.stack([np.bincount(cell, points[:, k], n) for k in range(3)], axis=1)
    votes = np.bincount(cell * num_classes + labels, minlength=n * num_classes)
    return centre / counts[:, None], votes.reshape(n, num_classes).argmax(axis=1)


def current_support(
    support: MaterialSupport | None, points: Tensor, labels: Tensor, num_classes: int, fill_m: float
) -> MaterialSupport:
    """`support` if it holds these very tensors, else a new support of them."""
    if support is not None and support.source[0] is points and support.source[1] is labels:
        return support
    return MaterialSupport(points, labels, num_classes, fill_m)
