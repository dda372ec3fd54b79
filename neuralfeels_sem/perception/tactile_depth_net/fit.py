"""Training loop of the tactile depth network on composed simulator frames.

Loss, at the full 320 x 240 resolution the network's maps are upsampled to: binary
cross-entropy plus a soft Dice term on the contact mask (Dice keeps small touches from
drowning in the no-contact pixels), and the L1 error of the press depth in millimetres
over the true contact pixels.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from tqdm import tqdm

from neuralfeels_sem.perception.tactile_depth_net.compose import Augmentation, compose_frames
from neuralfeels_sem.perception.tactile_depth_net.model import (
    TactileDepthNet,
    build_model,
    full_resolution,
    preprocess,
)

log = logging.getLogger(__name__)


@dataclass
class FitSettings:
    """Defaults and range checks: TrainTactileDepthTaskConfig (configs/tactile_depth.py)."""

    width: int
    input_size: tuple[int, int]
    epochs: int
    batch_size: int
    lr: float
    depth_weight: float  # weight of the depth L1 (per mm) beside the mask terms
    augmentation: Augmentation
    seed: int


def fit(
    change: np.ndarray,
    press_mm: np.ndarray,
    backgrounds: np.ndarray,
    settings: FitSettings,
) -> tuple[TactileDepthNet, list[dict]]:
    """Train from scratch; returns the model (eval mode) and the loss history per epoch."""
    torch.manual_seed(settings.seed)
    rng = np.random.default_rng(settings.seed)
    model = build_model(settings.width)
    optimizer = torch.optim.AdamW(model.parameters(), lr=settings.lr, weight_decay=1e-4)
    steps_per_epoch = max(1, len(change) // settings.batch_size)
    schedule = torch.optim.lr_scheduler.OneCycleLR(
        optimizer, settings.lr, total_steps=settings.epochs * steps_per_epoch, pct_start=0.15
    )
    history = []
    for epoch in range(settings.epochs):
        model.train()
        start, totals = time.perf_counter(), np.zeros(3)
        order = rng.permutation(len(change))[: steps_per_epoch * settings.batch_size]
        batches = order.reshape(steps_per_epoch, settings.batch_size)
        for batch in tqdm(batches, desc=f"epoch {epoch + 1}/{settings.epochs}", unit="batch"):
            bg = backgrounds[rng.integers(len(backgrounds), size=len(batch))]
            frames, given = compose_frames(
                change[batch].astype(np.float32), bg, rng, settings.augmentation
            )
            x = preprocess(frames, given, settings.input_size)
            target = torch.from_numpy(press_mm[batch].astype(np.float32))
            losses = _losses(model, x, target, settings.depth_weight)
            optimizer.zero_grad(set_to_none=True)
            losses[0].backward()
            optimizer.step()
            schedule.step()
            totals += [float(v.detach()) for v in losses]
        mean = [float(v) for v in totals / len(batches)]
        history.append(
            {
                "epoch": epoch + 1,
                "loss": round(mean[0], 5),
                "mask_loss": round(mean[1], 5),
                "depth_l1_mm": round(mean[2], 5),
                "wall_s": round(time.perf_counter() - start, 1),
            }
        )
        log.info("tactile depth epoch %d: %s", epoch + 1, history[-1])
    return model.eval(), history


def _losses(
    model: TactileDepthNet, x: torch.Tensor, press_mm: torch.Tensor, depth_weight: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(total, mask loss, depth L1 in mm over true contact pixels)."""
    logits, press = model(x)
    logits, press = full_resolution(logits), full_resolution(press)
    contact = (press_mm > 0).float()
    bce = F.binary_cross_entropy_with_logits(logits, contact)
    prob = torch.sigmoid(logits)
    dice = 1.0 - (2.0 * (prob * contact).sum() + 1.0) / (prob.sum() + contact.sum() + 1.0)
    inside = contact.sum().clamp(min=1.0)
    depth_l1 = ((press - press_mm).abs() * contact).sum() / inside
    mask_loss = bce + dice
    return mask_loss + depth_weight * depth_l1, mask_loss.detach(), depth_l1.detach()
