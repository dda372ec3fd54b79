"""The training loop: AdamW, augmentation, early stopping on validation accuracy, resumable.

(The whole training run around it, from an image folder to classifier.pt: train.py.)

The run directory holds `last.pt` (model, optimiser, epoch, RNG and early-stopping
state, written after every epoch) and `best.pt` (the best model so far, in the
`classifier.pt` format). A run that finds `last.pt` continues from the next epoch
with the same random stream, so an interrupted run ends where an uninterrupted one
would.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn
from tqdm import tqdm

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.classifier.checkpoint import save_checkpoint
from neuralfeels_sem.perception.classifier.finetune import MixedDraw
from neuralfeels_sem.perception.classifier.predict import predict_probs
from neuralfeels_sem.perception.classifier.transforms import augment, normalize, to_tensor

log = logging.getLogger(__name__)

LAST = "last.pt"
BEST = "best.pt"
LR_SCHEDULES = ("constant", "cosine")


@dataclass
class TrainSettings:
    batch_size: int = 32
    lr: float = 3e-4
    weight_decay: float = 1e-5
    max_epochs: int = 100
    patience: int = 10
    rotation_deg: float = 30.0
    brightness: float = 0.2
    contrast: float = 0.2
    color_gain: float = 0.1
    seed: int = 0
    lr_schedule: str = "constant"  # constant | cosine (to min_lr_ratio * lr at max_epochs)
    min_lr_ratio: float = 0.01

    def __post_init__(self) -> None:
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"lr_schedule={self.lr_schedule!r} is not one of {LR_SCHEDULES}")
        if not 0.0 <= self.min_lr_ratio <= 1.0:
            raise ValueError(f"min_lr_ratio={self.min_lr_ratio} must be in [0, 1]")

    def lr_at(self, progress: float) -> float:
        """Learning rate at `progress` = finished share of max_epochs (0 .. 1)."""
        if self.lr_schedule == "constant":
            return self.lr
        floor = self.min_lr_ratio * self.lr
        return floor + 0.5 * (self.lr - floor) * (1.0 + math.cos(math.pi * min(progress, 1.0)))


@dataclass
class TrainResult:
    best_epoch: int  # 1-based epoch whose model is in best.pt
    best_val_accuracy: float
    epochs_run: int
    stopped_early: bool
    resumed_from_epoch: int
    history: list[dict] = field(default_factory=list)


def fit(
    model: nn.Module,
    train_images: np.ndarray,
    train_labels: np.ndarray,
    val_images: np.ndarray,
    val_labels: np.ndarray,
    settings: TrainSettings,
    run_dir: Path,
    class_names: list[str],
    input_size: int,
    mean: list[float],
    std: list[float],
    device: torch.device,
    resume_from: Path | None = None,
    checkpoint_meta: dict | None = None,
    draw: MixedDraw | None = None,
) -> TrainResult:
    """Train in place; the best model (by validation accuracy) ends up in run_dir/best.pt.

    `checkpoint_meta` goes into every saved checkpoint's meta (e.g. `crop_px`, which
    inference needs to preprocess as training did, so best.pt is usable on its own);
    `draw` (finetune.py) orders each epoch over train_images = [real; extra]."""
    if len(train_images) < 2 or len(val_images) < 1:
        raise DataError(
            f"too few images to train ({len(train_images)} train, {len(val_images)} validation); collect more"
        )
    if train_images.shape[1:3] != (input_size, input_size):
        raise ValueError(f"train images {train_images.shape} are not at input_size {input_size}")
    optimizer, generator, state = _start(model, settings, device, resume_from, run_dir)
    resumed_from = state["epoch"]
    meta = {**(checkpoint_meta or {}), "settings": asdict(settings)}
    loop = _Loop(
        model, optimizer, generator, settings, device, class_names, input_size, mean, std, meta
    )
    loop.draw = draw
    stopped = state["since_best"] >= settings.patience
    epochs = tqdm(
        range(state["epoch"], settings.max_epochs),
        initial=state["epoch"],
        total=settings.max_epochs,
        desc="epochs",
        unit="epoch",
    )
    for epoch in epochs:
        if stopped:
            break
        record = loop.train_epoch(epoch, train_images, train_labels)
        loop.validate(epoch, record, train_images, val_images, val_labels, state, run_dir)
        epochs.set_postfix(
            loss=f"{record['train_loss']:.3f}",
            acc=f"{record['train_accuracy']:.3f}",
            val=f"{record['val_accuracy']:.3f}",
            best=f"{state['best_val']:.3f}",
        )
        stopped = state["since_best"] >= settings.patience
        if stopped:
            log.info("early stop: no better validation accuracy for %d epochs", settings.patience)
    epochs.close()
    return _finish(run_dir, settings, state, stopped, resumed_from)


def _start(
    model: nn.Module,
    settings: TrainSettings,
    device: torch.device,
    resume_from: Path | None,
    run_dir: Path,
) -> tuple[torch.optim.Optimizer, torch.Generator, dict]:
    """Optimiser, random stream and loop state: fresh, or restored from `resume_from`."""
    run_dir.mkdir(parents=True, exist_ok=True)
    model.to(device)
    optimizer = torch.optim.AdamW(
        model.parameters(), lr=settings.lr, weight_decay=settings.weight_decay
    )
    generator = torch.Generator().manual_seed(settings.seed)
    state = {"epoch": 0, "best_val": -1.0, "best_epoch": 0, "since_best": 0, "history": []}
    if resume_from is not None:
        state = _restore(resume_from, model, optimizer, generator)
        log.info("resuming from %s after epoch %d", resume_from, state["epoch"])
    return optimizer, generator, state


def _finish(
    run_dir: Path, settings: TrainSettings, state: dict, stopped: bool, resumed_from: int
) -> TrainResult:
    """Write history.json; fail when no epoch ran."""
    (run_dir / "history.json").write_text(json.dumps(state["history"], indent=2))
    if state["best_epoch"] == 0:
        raise DataError(
            f"no epoch was trained (task.max_epochs={settings.max_epochs}); raise max_epochs"
        )
    return TrainResult(
        best_epoch=state["best_epoch"],
        best_val_accuracy=state["best_val"],
        epochs_run=state["epoch"],
        stopped_early=stopped,
        resumed_from_epoch=resumed_from,
        history=state["history"],
    )


@dataclass
class _Loop:
    """What every epoch of `fit` shares: the model, its optimiser and the random stream."""

    model: nn.Module
    optimizer: torch.optim.Optimizer
    generator: torch.Generator
    settings: TrainSettings
    device: torch.device
    class_names: list[str]
    input_size: int
    mean: list[float]
    std: list[float]
    meta: dict  # goes into every saved checkpoint's meta
    draw: MixedDraw | None = None
    last_order: np.ndarray | None = None  # the latest epoch's draw

    def epoch_order(self, n: int) -> np.ndarray:
        """The indices of one epoch's training images, in the order they are trained on."""
        if self.draw is None:
            return torch.randperm(n, generator=self.generator).numpy()
        return self.draw(self.generator)

    def train_epoch(self, epoch: int, images: np.ndarray, labels: np.ndarray) -> dict:
        """One pass over the shuffled training set; its loss and accuracy."""
        settings, model, optimizer = self.settings, self.model, self.optimizer
        model.train()
        order = self.last_order = self.epoch_order(len(images))
        steps = (len(order) + settings.batch_size - 1) // settings.batch_size
        loss_sum, correct, seen = 0.0, 0, 0
        bar = tqdm(
            range(steps), desc=f"epoch {epoch + 1}/{settings.max_epochs}", unit="batch", leave=False
        )
        for step in bar:
            idx = order[step * settings.batch_size : (step + 1) * settings.batch_size]
            if len(idx) < 2:  # BatchNorm cannot train on a batch of one
                continue
            # A function of the global step, so a resumed run follows the same schedule.
            lr = settings.lr_at((epoch * steps + step) / (settings.max_epochs * steps))
            for group in optimizer.param_groups:
                group["lr"] = lr
            x = to_tensor(images[idx]).to(self.device)
            x = augment(
                x,
                self.generator,
                settings.rotation_deg,
                settings.brightness,
                settings.contrast,
                settings.color_gain,
            )
            y = torch.from_numpy(labels[idx]).to(self.device)
            logits = model(normalize(x, self.mean, self.std))
            loss = F.cross_entropy(logits, y)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            loss_sum += float(loss.detach()) * len(idx)
            correct += int((logits.argmax(1) == y).sum())
            seen += len(idx)
            bar.set_postfix(loss=f"{loss_sum / seen:.3f}", acc=f"{correct / seen:.3f}")
        record = {
            "epoch": epoch + 1,
            "train_loss": loss_sum / max(seen, 1),
            "train_accuracy": correct / max(seen, 1),
        }
        if self.draw is not None:  # what the epoch actually drew, to check the mix
            record["real_drawn"] = int((order < self.draw.primary).sum())
            record["extra_drawn"] = int((order >= self.draw.primary).sum())
        return record

    def validate(
        self,
        epoch: int,
        record: dict,
        train_images: np.ndarray,
        val_images: np.ndarray,
        val_labels: np.ndarray,
        state: dict,
        run_dir: Path,
    ) -> None:
        """Score the epoch on the validation set, keep the best model, write last.pt."""
        model, settings = self.model, self.settings
        # A mixed epoch's statistics are those of its draw (real and sim at the ratio), the
        # ones the weights were trained under (real-only statistics, tried on a small real +
        # sim mix, dropped validation to 0-17 % where these give 100 %).
        calibration = train_images if self.draw is None else train_images[self.last_order]
        recalibrate_batchnorm(
            model, calibration, self.mean, self.std, self.device, settings.batch_size
        )
        val_pred = predict_probs(model, val_images, self.mean, self.std, self.device).argmax(1)
        val_acc = float((val_pred == val_labels).mean())
        record["val_accuracy"] = val_acc
        record["lr_end"] = float(self.optimizer.param_groups[0]["lr"])
        state["history"].append(record)
        if val_acc > state["best_val"]:
            state.update(best_val=val_acc, best_epoch=epoch + 1, since_best=0)
            save_checkpoint(
                run_dir / BEST,
                model,
                self.class_names,
                self.input_size,
                self.mean,
                self.std,
                meta={**self.meta, "epoch": epoch + 1, "val_accuracy": val_acc},
            )
        else:
            state["since_best"] += 1
        state["epoch"] = epoch + 1
        _save_last(run_dir / LAST, model, self.optimizer, self.generator, state)
        log.info(
            "epoch %d: loss %.4f, train acc %.4f, val acc %.4f (best %.4f @ %d)",
            epoch + 1,
            record["train_loss"],
            record["train_accuracy"],
            val_acc,
            state["best_val"],
            state["best_epoch"],
        )


def recalibrate_batchnorm(
    model: nn.Module,
    images: np.ndarray,
    mean: list[float],
    std: list[float],
    device: torch.device,
    batch_size: int,
    max_images: int = 256,
) -> None:
    """Recompute BatchNorm running statistics for the current weights ("precise BN").

    Running averages lag behind fast-changing weights; early in training from scratch
    the eval-mode network is then near chance although the train-mode one already fits
    (measured here: 100 % train-mode vs 25 % eval-mode accuracy on the same images).
    Plain averages over a fixed, evenly spread subset of un-augmented training images
    make validation, early stopping and the saved model use statistics that match.
    """
    norms = [m for m in model.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm)]
    if not norms:
        return
    idx = np.linspace(0, len(images) - 1, min(max_images, len(images))).round().astype(int)
    momenta = [m.momentum for m in norms]
    for m in norms:
        m.reset_running_stats()
        m.momentum = None  # cumulative average over the batches below
    model.train()
    with torch.no_grad():
        for start in range(0, len(idx), batch_size):
            batch = idx[start : start + batch_size]
            if len(batch) < 2:
                continue
            model(normalize(to_tensor(images[batch]).to(device), mean, std))
    for m, momentum in zip(norms, momenta):
        m.momentum = momentum
    model.eval()


def _save_last(
    path: Path,
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    generator: torch.Generator,
    state: dict,
) -> None:
    payload = {
        "model": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "optimizer": optimizer.state_dict(),
        "generator": generator.get_state(),
        # Dropout and drop-connect draw from torch's global RNG.
        "torch_rng": torch.get_rng_state(),
        "cuda_rng": torch.cuda.get_rng_state_all() if torch.cuda.is_available() else [],
        "state": state,
    }
    tmp = path.with_suffix(".tmp")
    torch.save(payload, tmp)
    tmp.replace(path)


def _restore(
    path: Path, model: nn.Module, optimizer: torch.optim.Optimizer, generator: torch.Generator
) -> dict:
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        model.load_state_dict(payload["model"])
        optimizer.load_state_dict(payload["optimizer"])
    except (RuntimeError, KeyError, ValueError) as exc:
        raise DataError(
            f"cannot resume from {path} ({exc.__class__.__name__}: {str(exc).splitlines()[0]}); "
            "delete it or set task.resume=never"
        ) from exc
    generator.set_state(payload["generator"])
    torch.set_rng_state(payload["torch_rng"])
    if torch.cuda.is_available() and payload.get("cuda_rng"):
        torch.cuda.set_rng_state_all(payload["cuda_rng"])
    return payload["state"]
