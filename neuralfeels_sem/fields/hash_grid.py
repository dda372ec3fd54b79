"""Multiresolution hash-grid encoding (Instant-NGP, Mueller et al. 2022) in pure PyTorch.

Level l has resolution R_l = floor(base_resolution * per_level_scale^l) cells per axis,
so (R_l + 1)^3 vertices. Coarse levels whose vertices fit in the table are indexed densely
(one row per vertex, no collisions); finer levels hash the integer vertex coordinates with
the Instant-NGP primes into 2^log2_table_size rows. Each level owns only the rows it
needs, stacked in one (rows, features_per_level) table. Features are trilinearly
interpolated from the 8 corners of the cell holding the point and concatenated over levels.

With `sparse_grad=True` the table's gradient is a sparse COO tensor holding only the rows
the batch touched, so an optimiser step costs O(points), not O(table): use
`neuralfeels_sem.fields.optim.FieldAdam` (plain torch.optim.Adam rejects sparse grads).

On the CPU, float32 points go through fused kernels (hash_kernels.py) where either the
table or the points need a gradient, not both: the mapper's batches, every query, and
SDF gradients against a table that is not being trained (pose tracking). The same corner
rows, weights and features, several times less memory traffic. Points and table both
needing gradients (the eikonal term, which also differentiates the gradient) and every
other device take the PyTorch path below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from neuralfeels_sem.fields import hash_kernels
from neuralfeels_sem.fields.row_ops import gather_rows

# Instant-NGP / tiny-cuda-nn spatial hash primes (the first is 1 for cache coherence).
HASH_PRIMES = (1, 2654435761, 805459861)

# The 8 corners of a unit cell, as 0/1 offsets (x fastest).
_CORNERS = torch.tensor([[(i >> d) & 1 for d in range(3)] for i in range(8)], dtype=torch.long)


@dataclass
class HashGridConfig:
    """Multiresolution hash grid (`model.encoding`); defaults are the paper's except
    log2_table_size (CPU)."""

    num_levels: int = 16
    features_per_level: int = 2
    base_resolution: int = 16
    per_level_scale: float = 1.3819
    # The paper uses 24 (2^24 rows x 7 hashed levels: 1.1 GB of float32 before Adam). On a
    # CPU the step is bound by random row reads and writes: at 16, table and moments (22 MB)
    # stay in a 32 MB L3 cache, and the default run's mapper took about a third less CPU
    # than at 19 (147 MB) with the same maps (16 runs of the shipped objects within
    # -0.42..+0.79 points each, docs/field_and_mapper.md#table-size).
    log2_table_size: int = 16
    init_scale: float = 1e-4
    # Row-sparse table gradients (needs an optimiser that takes them: FieldAdam).
    sparse_grad: bool = True

    def __post_init__(self) -> None:
        for name in ("num_levels", "features_per_level", "base_resolution"):
            if getattr(self, name) < 1:
                raise ValueError(f"model.encoding.{name}={getattr(self, name)} must be >= 1")
        if self.per_level_scale < 1.0:
            raise ValueError(f"model.encoding.per_level_scale={self.per_level_scale} must be >= 1")
        if not 4 <= self.log2_table_size <= 30:
            raise ValueError(
                f"model.encoding.log2_table_size={self.log2_table_size} must be in [4, 30]"
            )
        if self.init_scale < 0:
            raise ValueError(f"model.encoding.init_scale={self.init_scale} must be >= 0")


class HashGridEncoding(nn.Module):
    """Encode points in the unit cube [0, 1]^3 as (N, num_levels * features_per_level)."""

    def __init__(self, config: HashGridConfig | None = None) -> None:
        super().__init__()
        config = config or HashGridConfig()  # ranges: HashGridConfig.__post_init__
        num_levels, features_per_level = config.num_levels, config.features_per_level
        base_resolution, per_level_scale = config.base_resolution, config.per_level_scale
        log2_table_size = config.log2_table_size
        self.num_levels = num_levels
        self.features_per_level = features_per_level
        self.base_resolution = base_resolution
        self.per_level_scale = per_level_scale
        self.log2_table_size = log2_table_size
        self.sparse_grad = config.sparse_grad
        table_size = 2**log2_table_size

        resolutions = [
            math.floor(base_resolution * per_level_scale**level) for level in range(num_levels)
        ]
        dense = [(r + 1) ** 3 <= table_size for r in resolutions]
        # Resolutions grow with the level, so the dense levels are a prefix.
        self.num_dense_levels = sum(dense)
        rows = [(r + 1) ** 3 if d else table_size for r, d in zip(resolutions, dense)]
        # Table layout: the hashed levels first, each at a multiple of the table size, so
        # a level's offset can be OR-ed into the hash (fewer passes over the big index
        # tensor); then the dense levels.
        num_hashed = num_levels - self.num_dense_levels
        offsets = [0] * num_levels
        start = num_hashed * table_size
        for level in range(num_levels):
            if dense[level]:
                offsets[level] = start
                start += rows[level]
            else:
                offsets[level] = (level - self.num_dense_levels) * table_size
        self.resolutions = resolutions
        self.level_rows = rows
        self.level_offsets = offsets
        self.register_buffer("_res", torch.tensor(resolutions, dtype=torch.long), persistent=False)
        self.register_buffer("_offsets", torch.tensor(offsets, dtype=torch.long), persistent=False)
        strides = torch.tensor([[1, r + 1, (r + 1) ** 2] for r in resolutions], dtype=torch.long)
        self.register_buffer("_strides", strides, persistent=False)
        # Row offset of each corner from the cell's lower corner, for the dense levels.
        self.register_buffer(
            "_dense_corner_offsets", (strides[:, None, :] * _CORNERS).sum(-1), persistent=False
        )
        self.table = nn.Parameter(torch.empty(sum(rows), features_per_level))
        self.init_scale = config.init_scale
        # Fused CPU kernels where they apply (see the module docstring); False forces the
        # PyTorch path (the tests compare both).
        self.fused_cpu = True
        self.reset_parameters()

    def reset_parameters(self) -> None:
        # Small uniform init as in Instant-NGP: features start near zero, the MLP breaks symmetry.
        nn.init.uniform_(self.table, -self.init_scale, self.init_scale)

    @property
    def out_dim(self) -> int:
        return self.num_levels * self.features_per_level

    def extra_repr(self) -> str:
        return (
            f"levels={self.num_levels}, features={self.features_per_level}, "
            f"resolutions={self.resolutions[0]}..{self.resolutions[-1]}, "
            f"log2_table={self.log2_table_size}, dense_levels={self.num_dense_levels}, "
            f"rows={self.table.shape[0]}, sparse_grad={self.sparse_grad}"
        )

    def corner_indices(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Table rows (N, L, 8) of each point's cell corners and trilinear weights (N, L, 8).

        Corner k has offset (k & 1, k >> 1 & 1, k >> 2 & 1) from the cell's lower corner.
        Built per axis and combined by broadcasting: about 3x faster than materialising
        (N, L, 8, 3) corner coordinates, and autograd sees only products (cheap backward).
        """
        res = self._res.to(x.dtype)
        scaled = x[:, None, :] * res[None, :, None]  # (N, L, 3)
        # Points on the upper face use the last cell with offset 1, not a cell past the grid.
        cell = scaled.detach().floor().long().clamp_(min=0)
        cell = torch.minimum(cell, (self._res - 1)[None, :, None])
        frac = scaled - cell.to(x.dtype)
        n = x.shape[0]
        fx, fy, fz = frac.unbind(-1)
        wx = torch.stack([1.0 - fx, fx], dim=-1)  # (N, L, 2)
        wy = torch.stack([1.0 - fy, fy], dim=-1)
        wz = torch.stack([1.0 - fz, fz], dim=-1)
        weights = (
            wz[..., :, None, None] * wy[..., None, :, None] * wx[..., None, None, :]
        ).reshape(n, self.num_levels, 8)
        nd = self.num_dense_levels
        idx = torch.empty(n, self.num_levels, 8, dtype=torch.long, device=x.device)
        if nd > 0:
            base = (cell[:, :nd] * self._strides[:nd]).sum(-1) + self._offsets[:nd]  # (N, nd)
            torch.add(base[..., None], self._dense_corner_offsets[:nd], out=idx[:, :nd])
        if nd < self.num_levels:
            c = cell[:, nd:]
            step = torch.arange(2, device=x.device)
            mask = 2**self.log2_table_size - 1
            # (a ^ b ^ c) & mask == (a & mask) ^ (b & mask) ^ (c & mask), and the aligned
            # level offset sets only bits above the mask: apply both to the (N, Lh, 2) terms.
            hx = ((c[..., 0, None] + step) * HASH_PRIMES[0]) & mask
            hy = ((c[..., 1, None] + step) * HASH_PRIMES[1]) & mask
            hz = ((c[..., 2, None] + step) * HASH_PRIMES[2]) & mask | self._offsets[nd:, None]
            hyx = (hy[..., :, None] ^ hx[..., None, :]).reshape(n, -1, 1, 4)
            torch.bitwise_xor(hz[..., :, None], hyx, out=idx[:, nd:].view(n, -1, 2, 4))
        return idx, weights

    def forward(self, x: Tensor) -> Tensor:
        """Points (N, 3) in [0, 1]^3 (callers clamp) -> features (N, levels * features)."""
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"x must have shape (N, 3), got {tuple(x.shape)}")
        grad_on = torch.is_grad_enabled()
        trains, moves = grad_on and self.table.requires_grad, grad_on and x.requires_grad
        if self._fused(x):
            if not trains and not moves:
                return self._encode_fused(x, keep_corners=False)[0]
            if trains and not moves and self.sparse_grad:
                return _FusedSparseEncode.apply(self.table, x, self)
            if moves and not trains:  # SDF gradients against a fixed table (pose tracking)
                return _FusedInputGradEncode.apply(x, self)
        n = x.shape[0]
        idx, weights = self.corner_indices(x)
        idx = idx.reshape(-1)
        rows_shape = (n * self.num_levels, 8, self.features_per_level)
        trains_table = torch.is_grad_enabled() and self.table.requires_grad
        if trains_table and self.sparse_grad and not weights.requires_grad:
            # The mapper's step (points without a gradient): gather, interpolation and the
            # table's sparse gradient in one function with a cheap backward.
            out = _SparseInterpolate.apply(self.table, idx, weights.reshape(rows_shape[0], 1, 8))
            return out.reshape(n, self.out_dim)
        if not trains_table:
            feats = gather_rows(self.table, idx)  # queries: no graph, fastest gather
        elif self.sparse_grad:
            feats = _SparseGather.apply(self.table, idx)
        else:
            feats = F.embedding(idx, self.table)
        feats = feats.view(rows_shape)
        # Weighted sum over the 8 corners as one batched matmul (fast forward and backward).
        out = torch.bmm(weights.reshape(n * self.num_levels, 1, 8), feats)
        return out.reshape(n, self.out_dim)

    def _fused(self, x: Tensor) -> bool:
        return (
            self.fused_cpu
            and x.device.type == "cpu"
            and x.dtype == torch.float32
            and self.table.dtype == torch.float32
        )

    def _encode_fused(self, x: Tensor, keep_corners: bool) -> tuple[Tensor, np.ndarray, np.ndarray]:
        """Features (N, out_dim) by the fused CPU kernel, with the corner rows and weights
        (N, L, 8) when `keep_corners` (else empty arrays)."""
        n, shape = x.shape[0], (x.shape[0], self.num_levels, 8)
        rows_dtype = np.int32 if self.table.shape[0] < 2**31 else np.int64
        rows = np.empty(shape if keep_corners else (0, 0, 0), dtype=rows_dtype)
        weights = np.empty(shape if keep_corners else (0, 0, 0), dtype=np.float32)
        out = torch.empty(n, self.out_dim, dtype=torch.float32)
        hash_kernels.encode(
            x.detach().contiguous().numpy(), self.table.detach().numpy(), self._res.numpy(),
            self._offsets.numpy(), self.num_dense_levels, 2**self.log2_table_size - 1,
            rows, weights, out.numpy(),
        )  # fmt: skip
        return out, rows, weights


def sum_rows(idx: Tensor, values: Tensor, num_rows: int) -> tuple[Tensor, Tensor]:
    """Distinct sorted rows of `idx` (M,) and the sums of `values` (M, F) over each.

    The reduction behind a coalesced sparse gradient: one 32-bit sort (when the row count
    allows), then a sequential index_add over the sorted order (cache friendly).
    """
    key = idx.int() if num_rows < 2**31 else idx
    sorted_idx, perm = torch.sort(key)
    starts = torch.ones_like(sorted_idx, dtype=torch.bool)
    starts[1:] = sorted_idx[1:] != sorted_idx[:-1]
    rows = sorted_idx[starts].long()
    segment = torch.cumsum(starts, dim=0) - 1
    sums = values.new_zeros((rows.numel(), *values.shape[1:]))
    sums.index_add_(0, segment, gather_rows(values, perm))
    return rows, sums


class _SparseGather(torch.autograd.Function):
    """table[idx] whose table gradient is a coalesced sparse COO tensor (sorted, distinct rows).

    torch's embedding(sparse=True) leaves one gradient row per lookup (8 per level per
    point), and coalescing that in the optimiser cost more than the rest of the step.
    The backward is first-order only, which is all the eikonal loss needs (its second
    derivative flows through the interpolation weights, not through this gather).
    """

    @staticmethod
    def forward(ctx, table: Tensor, idx: Tensor) -> Tensor:
        ctx.save_for_backward(idx)
        ctx.table_shape = table.shape
        return gather_rows(table, idx)

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad: Tensor) -> tuple[Tensor, None]:
        (idx,) = ctx.saved_tensors
        rows, sums = sum_rows(idx, grad, ctx.table_shape[0])
        sparse = torch.sparse_coo_tensor(
            rows[None], sums, ctx.table_shape, is_coalesced=True, check_invariants=False
        )
        return sparse, None


class _SparseInterpolate(torch.autograd.Function):
    """bmm(weights, table[idx]) with the table's gradient as a coalesced sparse tensor.

    For points that need no gradient themselves (weights constant): the backward is then
    only the outer product weights x grad per corner, which is exactly what bmm's backward
    computes (one product per element, nothing summed) at a fraction of the cost of a
    batched matmul of 1 x 8 by 1 x F matrices, and no (N*L*8, F) gather stays in the graph.
    """

    @staticmethod
    def forward(ctx, table: Tensor, idx: Tensor, weights: Tensor) -> Tensor:
        ctx.save_for_backward(idx, weights)
        ctx.table_shape = table.shape
        feats = gather_rows(table, idx).view(weights.shape[0], 8, table.shape[1])
        return torch.bmm(weights, feats)

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad: Tensor) -> tuple[Tensor, None, None]:
        idx, weights = ctx.saved_tensors
        per_corner = (weights.transpose(1, 2) * grad).reshape(-1, ctx.table_shape[1])
        rows, sums = sum_rows(idx, per_corner, ctx.table_shape[0])
        sparse = torch.sparse_coo_tensor(
            rows[None], sums, ctx.table_shape, is_coalesced=True, check_invariants=False
        )
        return sparse, None, None


class _FusedSparseEncode(torch.autograd.Function):
    """The encoding by the fused CPU kernels, with the table's gradient as a coalesced
    sparse tensor (sorted distinct rows); for points that need no gradient themselves."""

    @staticmethod
    def forward(ctx, table: Tensor, x: Tensor, encoding: HashGridEncoding) -> Tensor:
        out, ctx.rows, ctx.weights = encoding._encode_fused(x, keep_corners=True)
        ctx.table_shape = table.shape
        return out

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad: Tensor) -> tuple[Tensor, None, None]:
        num_rows, num_features = ctx.table_shape
        words = (num_rows + 63) // 64
        rows, sums = hash_kernels.table_grad(
            ctx.rows, ctx.weights, grad.to(torch.float32).contiguous().numpy(),
            np.zeros(words, dtype=np.uint64), np.empty(words, dtype=np.int64), num_features,
        )  # fmt: skip
        sparse = torch.sparse_coo_tensor(
            torch.from_numpy(rows)[None], torch.from_numpy(sums), ctx.table_shape,
            is_coalesced=True, check_invariants=False,
        )  # fmt: skip
        return sparse, None, None


class _FusedInputGradEncode(torch.autograd.Function):
    """The encoding by the fused CPU kernel, differentiable with respect to the points only
    (first order): for SDF gradients against a table that is not trained meanwhile."""

    @staticmethod
    def forward(ctx, x: Tensor, encoding: HashGridEncoding) -> Tensor:
        ctx.x, ctx.encoding = x.detach().contiguous(), encoding
        return encoding._encode_fused(x, keep_corners=False)[0]

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad: Tensor) -> tuple[Tensor, None]:
        enc = ctx.encoding
        grad_x = torch.empty_like(ctx.x)
        hash_kernels.encode_input_grad(
            ctx.x.numpy(), enc.table.detach().numpy(), enc._res.numpy(), enc._offsets.numpy(),
            enc.num_dense_levels, 2**enc.log2_table_size - 1,
            grad.to(torch.float32).contiguous().numpy(), grad_x.numpy(),
        )  # fmt: skip
        return grad_x, None
