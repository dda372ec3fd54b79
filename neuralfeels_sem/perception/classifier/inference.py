"""The trained classifier made ready for inference on the run's device."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import torch
from torch import nn

from neuralfeels_sem.perception.classifier.model import fold_batch_norms, fold_same_padding
from neuralfeels_sem.perception.classifier.traced_cache import cached_trace
from neuralfeels_sem.perception.graphed import GraphedModel
from neuralfeels_sem.perception.onnx_cpu import OnnxModule, onnx_module


def inference_model(
    build: Callable[[], nn.Module],
    input_size: int,
    device: torch.device,
    cuda_graphs: bool,
    source: Path,
    cpu_runtime: str = "onnxruntime",
) -> nn.Module | OnnxModule:
    """The model of checkpoint file `source` (`build()`: eval mode, on `device`) for
    inference only, batch norms and symmetric paddings folded. On the CPU: exported to
    ONNX Runtime (`cpu_runtime=onnxruntime`, perception/onnx_cpu.py; outputs within float
    rounding) or traced and frozen (`torch`, traced_cache.py; to the bit), either cached
    by `source`'s content; on a GPU replayed from CUDA graphs (`cuda_graphs`,
    perception/graphed.py; within the GPU's own rounding)."""
    if device.type == "cpu" and cpu_runtime == "onnxruntime":
        return onnx_module(source, lambda: _folded(build()), (3, input_size, input_size))
    if device.type == "cpu":
        return cached_trace(source, input_size, lambda: _folded(build()))
    model = _folded(build())
    if cuda_graphs and device.type == "cuda":
        graphed = GraphedModel(model)
        graphed.capture((3, input_size, input_size), device)
        return graphed
    return model


def _folded(model: nn.Module) -> nn.Module:
    return fold_same_padding(fold_batch_norms(model))
