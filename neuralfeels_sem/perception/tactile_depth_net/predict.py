"""Contact depth of DIGIT frames from a trained tactile depth network (source=net)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import load_checkpoint
from neuralfeels_sem.perception.tactile_depth_net.model import (
    TactileDepthNet,
    full_resolution,
    preprocess,
    to_depth,
)
from neuralfeels_sem.utils.paths import ASSETS_DIR

SHIPPED_CHECKPOINT = ASSETS_DIR / "tactile_depth" / "tactile_depth.pt"


class DepthNetPredictor:
    """Loads the checkpoint on first use (constructing one does no I/O) and predicts depth.

    Args:
        checkpoint: a tactile_depth.pt; None = the shipped asset.
        min_contact_px: a predicted contact smaller than this many pixels counts as none.
        device: where the network runs (the run's `device`).
    """

    def __init__(
        self,
        checkpoint: str | Path | None = None,
        min_contact_px: int = 150,
        device: str | torch.device = "cpu",
    ) -> None:
        self.path = Path(checkpoint).expanduser() if checkpoint else SHIPPED_CHECKPOINT
        self.min_contact_px = int(min_contact_px)
        self.device = torch.device(device)
        self._model: TactileDepthNet | None = None
        self.input_size: tuple[int, int] | None = None

    def load(self) -> TactileDepthNet:
        if self._model is None:
            ckpt = load_checkpoint(self.path)
            try:
                self._model = ckpt.build()
            except (RuntimeError, ValueError) as exc:  # tensors of another shape or width
                raise DataError(
                    f"tactile depth checkpoint {self.path} does not fit its own width "
                    f"{ckpt.width}; retrain it with task=train_tactile_depth"
                ) from exc
            self._model.to(self.device)
            self.input_size = ckpt.input_size
        return self._model

    @torch.inference_mode()
    def predict(self, images: np.ndarray, backgrounds: np.ndarray) -> np.ndarray:
        """(N, 320, 240, 3) uint8 RGB frames and their no-contact backgrounds -> (N, 320,
        240) float32 depth in metres along the sensor's +z, 0 off-contact."""
        model = self.load()
        batch = preprocess(images, backgrounds, self.input_size).to(self.device)
        logits, press_mm = model(batch)
        return to_depth(full_resolution(logits), full_resolution(press_mm), self.min_contact_px)
