"""How many optimiser steps a frame gets (`mapping.mapper.steps_policy`).

`fixed`: `steps_per_frame` on every frame. `surprise`: from `min_steps_per_frame` up to
`steps_per_frame`, by how much of the new frame the field does not explain yet, measured
before the steps on the frame's own points:
- geometry: the share of its camera points (a strided subsample) whose |SDF| exceeds the
  truncation band;
- material: the share of its usable labelled touches whose label differs from the class
  the field predicts at the touch's points (the mean of their logits).
The larger share sets the count, linearly. Early frames, new surface coming into view and
touches on a material the map does not show yet get the full count; frames the field
already predicts get the minimum. The first frame's warm-up block is not affected.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.perception.touch import TouchLabel

StepsPolicy = Literal["fixed", "surprise"]
STEPS_POLICIES = ("fixed", "surprise")
SURPRISE_CAMERA_POINTS = 256  # camera points checked per frame: enough for a share


@torch.no_grad()
def surprise(
    field: nn.Module,
    points: Mapping[str, np.ndarray],
    labels: Mapping[str, TouchLabel],
    truncation: float,
    device: torch.device,
) -> float:
    """In [0, 1]: the larger of the geometry and material shares the field gets wrong."""
    shares = [0.0]
    camera = points.get("camera")
    if camera is not None and len(camera):
        stride = max(1, len(camera) // SURPRISE_CAMERA_POINTS)
        x = torch.as_tensor(camera[::stride], dtype=torch.float32, device=device)
        shares.append(float((field.sdf(x).abs() > truncation).float().mean()))
    judged = wrong = 0
    for finger, label in labels.items():
        pts = points.get(finger)
        if label is None or not label.usable or pts is None or not len(pts):
            continue
        x = torch.as_tensor(pts, dtype=torch.float32, device=device)
        predicted = int(field.material_logits(x).mean(dim=0).argmax())
        judged += 1
        wrong += predicted != label.label
    if judged:
        shares.append(wrong / judged)
    return max(shares)


def steps_for(share: float, min_steps: int, max_steps: int) -> int:
    """`min_steps` for a frame the field explains (share 0), `max_steps` for one it does
    not at all (share 1), linear between."""
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"surprise share {share} must be in [0, 1]")
    return min_steps + round((max_steps - min_steps) * share)
