"""Fine-tuning the classifier on one's own DIGIT data, mixed with simulated images.

`initial_checkpoint` loads the model to start from (`shipped` or a `classifier.pt`) and
refuses one trained on other classes. `MixedDraw` orders each epoch's training images
over `[primary; extra]` (real images first, then a second set, usually simulated): every
primary image once, plus as many extra images as make `real_ratio` of the epoch primary,
drawn without replacement while the extra set lasts and with replacement beyond it, all
shuffled together, so each batch holds about `real_ratio` real images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier.checkpoint import ClassifierCheckpoint, load_checkpoint
from neuralfeels_sem.perception.classifier.dataset import resolve_path
from neuralfeels_sem.perception.classifier.infer import SHIPPED_CHECKPOINT

SHIPPED = "shipped"


def initial_checkpoint(init_from: str, class_names: list[str]) -> ClassifierCheckpoint:
    """The checkpoint `task.init_from` names: `shipped`, a classifier.pt or its run directory."""
    path = SHIPPED_CHECKPOINT if init_from == SHIPPED else resolve_path(init_from)
    if path.is_dir():
        path = path / "classifier.pt"
    checkpoint = load_checkpoint(path)
    if checkpoint.class_names != list(class_names):
        raise ConfigError(
            f"task.init_from={init_from} was trained on classes {checkpoint.class_names}, not "
            f"materials={list(class_names)}: set materials to its classes or task.init_from=null"
        )
    return checkpoint


@dataclass(frozen=True)
class MixedDraw:
    """Each epoch's order over `primary` real images followed by `extra` ones."""

    primary: int
    extra: int
    real_ratio: float

    def __post_init__(self) -> None:
        if self.primary < 1 or self.extra < 0:
            raise ValueError(
                f"MixedDraw needs primary >= 1, extra >= 0 ({self.primary}, {self.extra})"
            )
        if not 0.0 < self.real_ratio <= 1.0:
            raise ValueError(f"real_ratio={self.real_ratio} must be in (0, 1]")

    @property
    def extra_per_epoch(self) -> int:
        """How many extra images an epoch draws beside every primary image."""
        if self.extra == 0:
            return 0
        return int(round(self.primary * (1.0 - self.real_ratio) / self.real_ratio))

    def __call__(self, generator: torch.Generator) -> np.ndarray:
        """One epoch's shuffled indices into `[primary; extra]`."""
        count = self.extra_per_epoch
        if count <= self.extra:
            extra = torch.randperm(self.extra, generator=generator)[:count]
        else:  # fewer extra images than the ratio asks for: some are drawn twice
            extra = torch.randint(0, self.extra, (count,), generator=generator)
        order = torch.cat([torch.arange(self.primary), self.primary + extra])
        return order[torch.randperm(len(order), generator=generator)].numpy()
