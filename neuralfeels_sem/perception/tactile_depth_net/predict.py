"""Contact depth of DIGIT frames from a trained tactile depth network (source=net)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.graphed import GraphedModel
from neuralfeels_sem.perception.onnx_cpu import OnnxModule, check_cpu_runtime, onnx_module
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import load_checkpoint
from neuralfeels_sem.perception.tactile_depth_net.model import (
    TactileDepthNet,
    full_resolution,
    preprocess,
    to_depth,
)
from neuralfeels_sem.utils.paths import ASSETS_DIR

SHIPPED_CHECKPOINT = ASSETS_DIR / "tactile_depth" / "tactile_depth.pt"
# A frame's fingers go in one batch (perception/tactile_depth.py): four DIGITs, or fewer.
GRAPH_BUCKETS = (1, 2, 4, 8)


class FullResolution(nn.Module):
    """The network and the upsampling of its maps to the DIGIT frame, as one forward (one
    CUDA graph on a GPU: the upsampling alone is dozens of launches from Python)."""

    def __init__(self, model: TactileDepthNet) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        logits, press_mm = self.model(x)
        return full_resolution(logits), full_resolution(press_mm)


class DepthNetPredictor:
    """Loads the checkpoint on first use (constructing one does no I/O) and predicts depth.

    Args:
        checkpoint: a tactile_depth.pt; None = the shipped asset.
        min_contact_px: a predicted contact smaller than this many pixels counts as none.
        device: where the network runs (the run's `device`).
        cuda_graphs: on a GPU, replay the forward from CUDA graphs (perception/graphed.py),
            captured when the checkpoint is loaded; false: eager.
        cpu_runtime: on the CPU, `onnxruntime` (perception/onnx_cpu.py: about half the time
            a frame, depth within float rounding) or `torch` (eager).
    """

    def __init__(
        self,
        checkpoint: str | Path | None = None,
        min_contact_px: int = 150,
        device: str | torch.device = "cpu",
        cuda_graphs: bool = True,
        cpu_runtime: str = "onnxruntime",
    ) -> None:
        self.path = Path(checkpoint).expanduser() if checkpoint else SHIPPED_CHECKPOINT
        self.min_contact_px = int(min_contact_px)
        self.device = torch.device(device)
        self.cuda_graphs = bool(cuda_graphs)
        check_cpu_runtime("tactile_depth.cpu_runtime", cpu_runtime)
        self.cpu_runtime = cpu_runtime
        self._model: TactileDepthNet | None = None
        self._forward: FullResolution | GraphedModel | OnnxModule | None = None
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
            self._forward = FullResolution(self._model).eval()
            if self.device.type == "cpu" and self.cpu_runtime == "onnxruntime":
                forward = self._forward  # already built: export it as it is
                shape = (3, *self.input_size)
                self._forward = onnx_module(self.path, lambda: forward, shape, outputs=2)
            if self.cuda_graphs and self.device.type == "cuda":
                self._forward = GraphedModel(self._forward, GRAPH_BUCKETS)
                self._forward.capture((3, *self.input_size), self.device)
        return self._model

    @torch.inference_mode()
    def predict(self, images: np.ndarray, backgrounds: np.ndarray) -> np.ndarray:
        """(N, 320, 240, 3) uint8 RGB frames and their no-contact backgrounds -> (N, 320,
        240) float32 depth in metres along the sensor's +z, 0 off-contact."""
        self.load()
        batch = preprocess(images, backgrounds, self.input_size).to(self.device)
        logits, press_mm = self._forward(batch)
        return to_depth(logits, press_mm, self.min_contact_px)
