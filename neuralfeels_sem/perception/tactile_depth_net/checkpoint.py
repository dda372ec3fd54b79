"""`tactile_depth.pt`: a trained tactile depth network and what inference needs, as plain types.

Layout (loadable with `torch.load(..., weights_only=True)`):
    format: "neuralfeels_sem.tactile_depth/1"
    arch: "tactile-depth-unet"
    state_dict: model tensors (fp32, or fp16 for the shipped asset)
    width: int (channels at the first scale)
    input_size: [rows, cols] the frame is area-downsampled to
    meta: dict of plain values (provenance: data counts, held-out figures, settings)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.tactile_depth_net.model import ARCH, TactileDepthNet, build_model
from neuralfeels_sem.utils.payload_file import float_state, load_payload, save_payload, stored_state

FORMAT = "neuralfeels_sem.tactile_depth/1"


@dataclass
class DepthNetCheckpoint:
    state_dict: dict[str, torch.Tensor]
    width: int
    input_size: tuple[int, int]
    meta: dict[str, Any] = field(default_factory=dict)

    def build(self) -> TactileDepthNet:
        """The model in eval mode, in fp32 (fp16 storage is only for shipping)."""
        model = build_model(self.width)
        model.load_state_dict(float_state(self.state_dict), strict=True)
        return model.eval()


def save_checkpoint(
    path: str | Path,
    model: TactileDepthNet,
    input_size: tuple[int, int],
    meta: dict[str, Any] | None = None,
    fp16: bool = False,
) -> Path:
    path = Path(path)
    payload = {
        "format": FORMAT,
        "arch": ARCH,
        "state_dict": stored_state(model, fp16),
        "width": int(model.width),
        "input_size": [int(v) for v in input_size],
        "meta": dict(meta or {}),
    }
    return save_payload(payload, path)


def load_checkpoint(path: str | Path) -> DepthNetCheckpoint:
    path = Path(path)
    payload = load_payload(
        path, "tactile depth checkpoint", FORMAT, ARCH, "train one with task=train_tactile_depth"
    )
    size = payload.get("input_size")
    if not (isinstance(size, list) and len(size) == 2 and all(int(v) >= 16 for v in size)):
        raise DataError(
            f"tactile depth checkpoint {path} has input_size {size}; expected [rows, cols] >= 16"
        )
    return DepthNetCheckpoint(
        state_dict=payload["state_dict"],
        width=int(payload["width"]),
        input_size=(int(size[0]), int(size[1])),
        meta=dict(payload.get("meta", {})),
    )
