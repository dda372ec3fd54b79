"""frozen_parameters: gradients with respect to inputs only, parameters restored after."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from neuralfeels_sem.utils.frozen import frozen_parameters


def test_a_graph_recorded_frozen_differentiates_the_input_only() -> None:
    torch.manual_seed(0)
    module = nn.Sequential(nn.Linear(3, 8), nn.ReLU(), nn.Linear(8, 1))
    module[0].bias.requires_grad_(False)  # already frozen: stays frozen after
    x = torch.randn(5, 3, requires_grad=True)
    with frozen_parameters(module):
        y = module(x).sum()
        assert not any(p.requires_grad for p in module.parameters())
    (grad_x,) = torch.autograd.grad(y, x)  # the backward after the exit
    assert grad_x.abs().sum() > 0
    assert all(p.grad is None for p in module.parameters())
    assert [p.requires_grad for p in module.parameters()] == [True, False, True, True]


def test_parameters_are_restored_when_the_body_raises() -> None:
    module = nn.Linear(2, 2)
    with pytest.raises(RuntimeError), frozen_parameters(module):
        raise RuntimeError("boom")
    assert all(p.requires_grad for p in module.parameters())
