"""`classifier.pt`: a trained classifier with everything inference needs, as plain types.

Layout (loadable with `torch.load(..., weights_only=True)`):
    format: "neuralfeels_sem.classifier/1"
    arch: "efficientnet-b0"
    state_dict: model tensors (fp32, or fp16 for the shipped asset)
    class_names: list[str], in output order
    input_size: int (square side in pixels)
    mean, std: list[float] (RGB normalisation after scaling to [0, 1])
    meta: dict of plain values (provenance: data counts, accuracies, settings)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch import nn

from neuralfeels_sem.perception.classifier.model import ARCH, build_model
from neuralfeels_sem.utils.payload_file import float_state, load_payload, save_payload, stored_state

FORMAT = "neuralfeels_sem.classifier/1"


@dataclass
class ClassifierCheckpoint:
    state_dict: dict[str, torch.Tensor]
    class_names: list[str]
    input_size: int
    mean: list[float]
    std: list[float]
    meta: dict[str, Any] = field(default_factory=dict)

    def build(self, device: torch.device | str = "cpu") -> nn.Module:
        """The model in eval mode, in fp32 (fp16 storage is only for shipping)."""
        model = build_model(len(self.class_names))
        model.load_state_dict(float_state(self.state_dict), strict=True)
        return model.to(device).eval()


def save_checkpoint(
    path: str | Path,
    model: nn.Module,
    class_names: list[str],
    input_size: int,
    mean: list[float],
    std: list[float],
    meta: dict[str, Any] | None = None,
    fp16: bool = False,
) -> Path:
    path = Path(path)
    payload = {
        "format": FORMAT,
        "arch": ARCH,
        "state_dict": stored_state(model, fp16),
        "class_names": list(class_names),
        "input_size": int(input_size),
        "mean": [float(v) for v in mean],
        "std": [float(v) for v in std],
        "meta": dict(meta or {}),
    }
    return save_payload(payload, path)


def load_checkpoint(path: str | Path) -> ClassifierCheckpoint:
    path = Path(path)
    payload = load_payload(
        path, "classifier checkpoint", FORMAT, ARCH, "train one with task=train_classifier"
    )
    return ClassifierCheckpoint(
        state_dict=payload["state_dict"],
        class_names=list(payload["class_names"]),
        input_size=int(payload["input_size"]),
        mean=list(payload["mean"]),
        std=list(payload["std"]),
        meta=dict(payload.get("meta", {})),
    )
