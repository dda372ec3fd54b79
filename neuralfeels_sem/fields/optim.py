"""FieldAdam: Adam for dense gradients, lazy (row-sparse) Adam for sparse ones.

The hash table has millions of rows of which one step touches a few hundred thousand.
Dense Adam updates every row (and its two moment buffers) each step: at the paper's 2^24
table that is about 5 s of CPU per step on this project's 2-core machines (bench_field). With `HashGridEncoding(sparse_grad=True)` the
table's gradient is a sparse COO tensor, and FieldAdam updates only the rows it holds, so
a step costs O(points). Rows absent from a step keep their moments unchanged ("lazy
Adam", as torch.optim.SparseAdam); bias correction uses the parameter's step count.
A parameter first updated with a sparse gradient keeps its moments in one tensor
`moments` (rows, 2, ...) (see `moments()`); others use torch Adam's state names. On the
CPU a float32 table's sparse update runs as one fused loop over its rows
(hash_kernels.adam_rows): the same arithmetic with one pass over the rows' memory.

Config: `mapping.optimizer` is an OptimizerConfig (below): `_target_: ...FieldAdam`,
`_partial_: true`, so `instantiate` gives `factory(field.parameters())`, the same call as
torch.optim.Adam. FieldAdam's keyword defaults are the config's, and its ranges are checked
once, by OptimizerConfig.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import torch
from torch import Tensor

from neuralfeels_sem.fields import hash_kernels
from neuralfeels_sem.fields.row_ops import copy_rows_, gather_rows

DEFAULT_BETAS = (0.9, 0.999)


@dataclass
class OptimizerConfig:
    """`mapping.optimizer`; FieldAdam takes the hash grid's row-sparse gradients
    (model.encoding.sparse_grad)."""

    _target_: str = "neuralfeels_sem.fields.optim.FieldAdam"
    _partial_: bool = True
    lr: float = 3.0e-3
    betas: list[float] = field(default_factory=lambda: list(DEFAULT_BETAS))
    eps: float = 1.0e-8
    weight_decay: float = 0.0

    def __post_init__(self) -> None:
        if self.lr <= 0:
            raise ValueError(f"mapping.optimizer.lr={self.lr} must be > 0")
        if len(self.betas) != 2 or not all(0.0 <= b < 1.0 for b in self.betas):
            raise ValueError(
                f"mapping.optimizer.betas={list(self.betas)} must be two values in [0, 1)"
            )
        if self.eps < 0 or self.weight_decay < 0:
            raise ValueError(
                f"mapping.optimizer eps={self.eps} and weight_decay={self.weight_decay} must be >= 0"
            )


class FieldAdam(torch.optim.Optimizer):
    """Adam (torch's update rule, L2 weight decay) that also takes row-sparse gradients."""

    def __init__(
        self,
        params: Iterable[Tensor] | Iterable[dict],
        lr: float = OptimizerConfig.lr,
        betas: tuple[float, float] = DEFAULT_BETAS,
        eps: float = OptimizerConfig.eps,
        weight_decay: float = OptimizerConfig.weight_decay,
    ) -> None:
        OptimizerConfig(lr=lr, betas=list(betas), eps=eps, weight_decay=weight_decay)  # ranges
        defaults = {"lr": lr, "betas": tuple(betas), "eps": eps, "weight_decay": weight_decay}
        super().__init__(params, defaults)
        # Fused CPU update of sparse rows where it applies; False forces the PyTorch path.
        self.fused_cpu = True

    @torch.no_grad()
    def step(self, closure=None):  # noqa: ANN001 (the torch.optim signature)
        loss = None
        if closure is not None:
            with torch.enable_grad():
                loss = closure()
        for group in self.param_groups:
            beta1, beta2 = group["betas"]
            for p in group["params"]:
                if p.grad is None:
                    continue
                state = self.state[p]
                if not state:
                    state["step"] = 0
                    if p.grad.is_sparse:
                        # Both moments of a row side by side: one gather and one scatter
                        # per step instead of two of each (random rows of a large table).
                        state["moments"] = p.new_zeros((p.shape[0], 2, *p.shape[1:]))
                    else:
                        state["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
                        state["exp_avg_sq"] = torch.zeros_like(
                            p, memory_format=torch.preserve_format
                        )
                state["step"] += 1
                step = state["step"]
                # Fold both bias corrections into the step size (as torch's Adam does).
                step_size = group["lr"] * math.sqrt(1 - beta2**step) / (1 - beta1**step)
                if p.grad.is_sparse:
                    fused = self.fused_cpu and _fusable(p, state)
                    update = _fused_sparse_update if fused else _sparse_update
                    update(p, p.grad, state, beta1, beta2, step_size, group)
                else:
                    _dense_update(p, p.grad, state, beta1, beta2, step_size, group)
        return loss


def _dense_update(
    p: Tensor, grad: Tensor, state: dict, beta1: float, beta2: float, step_size: float, group: dict
) -> None:
    if group["weight_decay"] != 0:
        grad = grad.add(p, alpha=group["weight_decay"])
    exp_avg, exp_avg_sq = moments(state)
    exp_avg.lerp_(grad, 1 - beta1)
    exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
    # eps is added to sqrt(v) / sqrt(bias2); folding sqrt(bias2) into step_size scales eps.
    denom = exp_avg_sq.sqrt().add_(group["eps"] * math.sqrt(1 - beta2 ** state["step"]))
    p.addcdiv_(exp_avg, denom, value=-step_size)


def _sparse_update(
    p: Tensor, grad: Tensor, state: dict, beta1: float, beta2: float, step_size: float, group: dict
) -> None:
    if grad.sparse_dim() != 1:
        raise ValueError(
            f"FieldAdam supports row-sparse gradients (sparse_dim 1), got {grad.sparse_dim()}"
        )
    rows, values = _coalesced_rows(grad)
    if rows.numel() == 0:
        return
    # Row gathers and scatters move each row as one word (row_ops.py): bit-identical, faster.
    p_rows = gather_rows(p, rows)
    if group["weight_decay"] != 0:
        values = values.add(p_rows, alpha=group["weight_decay"])
    if "moments" in state:
        mv = gather_rows(state["moments"], rows)
        # Out-of-place on the strided halves: contiguous results, faster arithmetic below.
        m = torch.lerp(mv[:, 0], values, 1 - beta1)
        v = torch.addcmul(mv[:, 1].mul(beta2), values, values, value=1 - beta2)
        copy_rows_(state["moments"], rows, torch.stack([m, v], dim=1))
    else:
        m = state["exp_avg"].index_select(0, rows).lerp_(values, 1 - beta1)
        v = state["exp_avg_sq"].index_select(0, rows).mul_(beta2)
        v.addcmul_(values, values, value=1 - beta2)
        state["exp_avg"].index_copy_(0, rows, m)
        state["exp_avg_sq"].index_copy_(0, rows, v)
    denom = v.sqrt().add_(group["eps"] * math.sqrt(1 - beta2 ** state["step"]))
    # index_copy of the updated rows: index_add_ on CPU is about 6x slower here.
    copy_rows_(p, rows, p_rows.addcdiv_(m, denom, value=-step_size))


def _fusable(p: Tensor, state: dict) -> bool:
    return (
        p.device.type == "cpu"
        and p.dtype == torch.float32
        and p.is_contiguous()
        and "moments" in state
        and state["moments"].is_contiguous()
    )


def _fused_sparse_update(
    p: Tensor, grad: Tensor, state: dict, beta1: float, beta2: float, step_size: float, group: dict
) -> None:
    """_sparse_update's arithmetic in one pass over the rows (hash_kernels.adam_rows)."""
    rows, values = _coalesced_rows(grad)
    if rows.numel() == 0:
        return
    eps = group["eps"] * math.sqrt(1 - beta2 ** state["step"])
    hash_kernels.adam_rows(
        p.detach().view(p.shape[0], -1).numpy(),
        state["moments"].view(p.shape[0], 2, -1).numpy(),
        rows.numpy(),
        values.to(torch.float32).reshape(rows.numel(), -1).contiguous().numpy(),
        beta1, beta2, step_size, eps, group["weight_decay"],
    )  # fmt: skip


def moments(state: dict) -> tuple[Tensor, Tensor]:
    """(first, second) Adam moments of a parameter's state, whichever layout it uses.

    Parameters first seen with a sparse gradient keep both in `moments` (rows, 2, ...);
    others keep torch Adam's `exp_avg` and `exp_avg_sq`.
    """
    if "moments" in state:
        return state["moments"][:, 0], state["moments"][:, 1]
    return state["exp_avg"], state["exp_avg_sq"]


def _coalesced_rows(grad: Tensor) -> tuple[Tensor, Tensor]:
    """(distinct rows, summed values) of a row-sparse gradient.

    The hash grid hands over sorted distinct rows, but autograd's accumulation drops the
    is_coalesced flag, so check the order (O(rows)) before paying for a full coalesce.
    """
    rows, values = grad._indices()[0], grad._values()
    if rows.numel() < 2 or bool((rows[1:] > rows[:-1]).all()):
        return rows, values
    grad = grad.coalesce()
    return grad.indices()[0], grad.values()
