"""EfficientNet-B0 with a head for the configured material classes (efficientnet-pytorch).

efficientnet-pytorch needs only torch (torchvision does not import with the CPU torch
build used here). No weights are downloaded: pretrained ImageNet weights come from a
local state dict in the library's own layout (`EfficientNet.from_pretrained` keys).
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import torch
from efficientnet_pytorch import EfficientNet
from efficientnet_pytorch.utils import Conv2dStaticSamePadding
from torch import nn

from neuralfeels_sem.core.errors import DataError

log = logging.getLogger(__name__)

ARCH = "efficientnet-b0"
HEAD_KEYS = ("_fc.weight", "_fc.bias")
# The library keeps TensorFlow's BatchNorm decay of 0.99 (PyTorch momentum 0.01): its
# running statistics lag hundreds of steps behind the weights, so on a few thousand
# tactile images the eval-mode model is near chance for many epochs. PyTorch's usual
# momentum 0.1 (decay 0.9) tracks within a few dozen steps. Not part of the weights.
BN_DECAY = 0.9


def build_model(num_classes: int, weights: str | Path | None = None) -> nn.Module:
    """EfficientNet-B0 with a fresh `num_classes` head, backbone from `weights` if given."""
    if num_classes < 2:
        raise ValueError(f"num_classes={num_classes} must be >= 2")
    model = EfficientNet.from_name(ARCH, num_classes=num_classes, batch_norm_momentum=BN_DECAY)
    if weights is not None:
        load_backbone(model, weights)
    return speed_up(model)


def speed_up(model: nn.Module) -> nn.Module:
    """Same numbers, faster on CPU: channels-last layout and the plain swish.

    Measured on this project's 2-core CPU, a training step at 112 px, batch 32: 46 img/s
    as the library builds it, 51 with the plain swish (the library's memory-saving one is
    a Python autograd function), 72 with channels-last weights and inputs as well (oneDNN's
    native layout; `to_tensor` already yields channels-last batches from NHWC images).
    """
    model.set_swish(memory_efficient=False)
    return model.to(memory_format=torch.channels_last)


def _fold(conv: nn.Conv2d, bn: nn.BatchNorm2d) -> nn.Identity:
    """Give `conv` the affine map of the eval-mode `bn` after it; the Identity replaces bn."""
    scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
    bias = bn.bias - bn.running_mean * scale
    if conv.bias is not None:
        bias = bias + conv.bias * scale
    weight = conv.weight * scale.view(-1, 1, 1, 1)
    conv.weight = nn.Parameter(weight.contiguous(memory_format=torch.channels_last))
    conv.bias = nn.Parameter(bias)
    return nn.Identity()


@torch.no_grad()
def fold_batch_norms(model: nn.Module) -> nn.Module:
    """The eval-mode model with every batch norm folded into the convolution before it,
    for inference only (it cannot be trained any more).

    The same predictions (logits within 3e-5 on the shipped model) without EfficientNet-B0's
    49 batch-norm passes: on this project's 2-core CPU `make bench` read 149 -> 172 images/s
    at 112 px on one thread (load 1.4-2.1). Each MBConv block applies its batch norms
    directly after `_expand_conv`, `_depthwise_conv` and `_project_conv`, the stem and head
    after `_conv_stem` and `_conv_head` (efficientnet-pytorch's forward).
    """
    if model.training:
        raise ValueError("fold_batch_norms needs a model in eval mode (running statistics)")
    model._bn0 = _fold(model._conv_stem, model._bn0)
    model._bn1 = _fold(model._conv_head, model._bn1)
    for block in model._blocks:
        if hasattr(block, "_expand_conv"):  # blocks with expand ratio 1 have none
            block._bn0 = _fold(block._expand_conv, block._bn0)
        block._bn1 = _fold(block._depthwise_conv, block._bn1)
        block._bn2 = _fold(block._project_conv, block._bn2)
    return model


def fold_same_padding(model: nn.Module) -> nn.Module:
    """Give each convolution whose TensorFlow 'same' padding is symmetric (the stride-1
    depthwise ones, 12 of EfficientNet-B0's) that padding itself, instead of a zero-pad
    pass that copies its input first. Asymmetric ones (stride 2) keep the pass.

    The same outputs to the bit on the shipped model; its forward took about 7 % less CPU
    time on this project's 2-core CPU at batch 4 and 12 (112 px, one thread, median of 12
    alternated calls, load 0.9): a zero-padded copy of the input per convolution is gone.
    """
    for conv in model.modules():
        if not isinstance(conv, Conv2dStaticSamePadding):
            continue
        if isinstance(conv.static_padding, nn.ZeroPad2d):
            left, right, top, bottom = conv.static_padding.padding
            if left == right and top == bottom:
                conv.static_padding = nn.Identity()
                conv.padding = (top, left)
    return model


def trace_for_cpu(model: nn.Module, input_size: int) -> nn.Module:
    """The inference model traced to TorchScript and frozen: the same outputs to the bit
    without the Python of its ~80 module calls per forward.

    On this project's 2-core CPU (112 px, one thread, median of 12 calls, load 0.5-1.0)
    a forward took 5-6 ms less at every batch size, i.e. 17-25 % less at the 2-3 crops of
    one frame's touches, which is about every call a mapping run makes. `model` must be in
    eval mode with its batch norms folded; it is traced at batch 1 and runs at any batch.
    torch 2.13 marks TorchScript deprecated (torch.export gave no speed-up here): where
    tracing fails, the model runs eagerly as before, with a warning.
    """
    if model.training:
        raise ValueError("trace_for_cpu needs a model in eval mode")
    example = _example(input_size)
    try:
        with torch.inference_mode(), warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            frozen = torch.jit.freeze(torch.jit.trace(model, example))
            warm_up(frozen, input_size)
    except Exception as exc:  # noqa: BLE001 (any tracing failure leaves the eager model)
        log.warning("classifier not traced (%s); running it eagerly", exc)
        return model
    return frozen


def warm_up(traced: torch.jit.ScriptModule, input_size: int) -> None:
    """TorchScript profiles a module's first two calls: make them before a run's loop."""
    example = _example(input_size)
    with torch.inference_mode():
        for _ in range(2):
            traced(example)


def _example(input_size: int) -> torch.Tensor:
    """One blank input in the layout the model runs in (channels-last)."""
    return torch.zeros(1, 3, input_size, input_size).contiguous(memory_format=torch.channels_last)


def load_backbone(model: nn.Module, weights: str | Path) -> None:
    """Load every non-head tensor of a library-layout state dict; the head stays new.

    Strict: a missing or unexpected backbone key, or a shape mismatch, is an error (a
    wrong file must not half-load). The head is taken only if it already has this
    model's class count (e.g. weights saved from a model of the same classes).
    """
    path = Path(weights)
    if not path.is_file():
        raise DataError(
            f"classifier.weights={path} does not exist; give a local EfficientNet-B0 state dict"
        )
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise DataError(
            f"classifier.weights={path} is not a readable torch state dict ({exc})"
        ) from exc
    if isinstance(state, dict) and "state_dict" in state and isinstance(state["state_dict"], dict):
        state = state["state_dict"]
    own = model.state_dict()
    backbone = {k: v for k, v in state.items() if k not in HEAD_KEYS}
    missing = sorted(set(own) - set(HEAD_KEYS) - set(backbone))
    unexpected = sorted(set(backbone) - set(own))
    if missing or unexpected:
        raise DataError(
            f"classifier.weights={path} is not an EfficientNet-B0 state dict in efficientnet-pytorch layout "
            f"({len(missing)} missing keys e.g. {missing[:2]}, {len(unexpected)} unexpected e.g. {unexpected[:2]})"
        )
    bad = [k for k, v in backbone.items() if tuple(v.shape) != tuple(own[k].shape)]
    if bad:
        raise DataError(
            f"classifier.weights={path} has wrong shapes for {bad[:3]}; expected EfficientNet-B0"
        )
    head_fits = all(k in state and tuple(state[k].shape) == tuple(own[k].shape) for k in HEAD_KEYS)
    if head_fits:
        backbone.update({k: state[k] for k in HEAD_KEYS})
    model.load_state_dict(backbone, strict=False)


def num_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
