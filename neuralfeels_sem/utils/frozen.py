"""Run a module with its parameters taking no gradient, for a while."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from torch import nn


@contextmanager
def frozen_parameters(module: nn.Module) -> Iterator[nn.Module]:
    """`module` with requires_grad off on every parameter that had it, restored on exit.

    A graph recorded inside differentiates with respect to its inputs only: its backward,
    also after the exit, neither computes nor accumulates parameter gradients. Only for
    the thread that trains the module (another thread would see its parameters frozen).
    """
    trainable = [p for p in module.parameters() if p.requires_grad]
    for p in trainable:
        p.requires_grad_(False)
    try:
        yield module
    finally:
        for p in trainable:
            p.requires_grad_(True)
