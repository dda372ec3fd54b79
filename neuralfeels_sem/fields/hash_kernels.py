"""Fused CPU kernels (numba) for the hash-grid encoding and FieldAdam's row-sparse update.

The PyTorch path of `hash_grid.py` builds the corner rows and weights as (N, L, 8) tensors,
gathers the rows, interpolates with a batched matmul, and reduces the table's gradient by
sorting every looked-up row; FieldAdam then gathers and scatters table and moment rows
once more. Each of those passes walks memory the previous one just left. On a CPU the
same arithmetic in one loop per pass is several times cheaper:

- `encode`: corners, weights, gather and interpolation per (point, level) in registers,
  keeping the corner rows and weights for the backward;
- `table_grad`: the table's gradient as sorted distinct rows and their sums, without a
  sort: a bitmap of the rows looked up, scanned in order, numbers them;
- `adam_rows`: Adam's moment and parameter update on those rows in one pass;
- `encode_input_grad`: the features' gradient with respect to the points (SDF gradients
  for pose tracking, against a table that is not being trained).

Arithmetic follows the PyTorch path operation for operation in float32 (same corner
order, same weight products), so the corner rows and weights are identical and the
features agree to float32 rounding of the 8-term sums (tests/fields/test_hash_kernels.py
compares both paths). The kernels release the GIL, so the frame producer's thread keeps
running beside a mapper step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Instant-NGP / tiny-cuda-nn spatial hash primes (as in hash_grid.py).
_P1 = np.int64(2654435761)
_P2 = np.int64(805459861)
_ONE = np.float32(1.0)
# De Bruijn sequence for the index of a 64-bit word's lowest set bit.
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_DEBRUIJN_INDEX = np.array(
    [0, 1, 48, 2, 57, 49, 28, 3, 61, 58, 50, 42, 38, 29, 17, 4,
     62, 55, 59, 36, 53, 51, 43, 22, 45, 39, 33, 30, 24, 18, 12, 5,
     63, 47, 56, 27, 60, 41, 37, 16, 54, 35, 52, 21, 44, 32, 23, 11,
     46, 26, 40, 15, 34, 20, 31, 10, 25, 14, 19, 9, 13, 8, 7, 6],
    dtype=np.int64,
)  # fmt: skip


@njit(cache=True, nogil=True)
def _cell(s: np.float32, res: np.int64) -> tuple[np.int64, np.float32]:
    """Lower cell index of a scaled coordinate (clamped to the grid) and its fraction."""
    c = np.int64(np.floor(s))
    c = min(max(c, np.int64(0)), res - 1)
    return c, s - np.float32(c)


@njit(cache=True, nogil=True)
def encode(x, table, res, offsets, num_dense, mask, rows, weights, out):  # noqa: ANN001
    """Features of points x (N, 3) in [0, 1]^3 into out (N, L * F); the corner rows
    (N, L, 8) and weights (N, L, 8) into rows and weights (skipped when they are empty)."""
    n_points, n_levels, n_feat = x.shape[0], res.shape[0], table.shape[1]
    keep = rows.shape[0] > 0
    row = np.empty(8, dtype=np.int64)
    w = np.empty(8, dtype=np.float32)
    for n in range(n_points):
        for lv in range(n_levels):
            wx, wy, wz = _locate(x, n, res[lv], offsets[lv], lv < num_dense, mask, row)
            for k in range(8):
                w[k] = wz[k >> 2] * wy[(k >> 1) & 1] * wx[k & 1]
            for f in range(n_feat):
                acc = np.float32(0.0)
                for k in range(8):
                    acc += w[k] * table[row[k], f]
                out[n, lv * n_feat + f] = acc
            if keep:
                for k in range(8):
                    rows[n, lv, k] = row[k]
                    weights[n, lv, k] = w[k]


@njit(cache=True, nogil=True)
def encode_input_grad(x, table, res, offsets, num_dense, mask, grad_out, grad_x):  # noqa: ANN001
    """grad_x (N, 3) = (d features / d x)^T grad_out for points x (N, 3), grad_out (N, L * F).

    Per level the features are sum_k w_k table[row_k], w_k = wz * wy * wx of the point's
    fractions in its cell, and d frac / d x = resolution (the cell is constant inside it)."""
    n_points, n_levels, n_feat = x.shape[0], res.shape[0], table.shape[1]
    row = np.empty(8, dtype=np.int64)
    for n in range(n_points):
        gx = gy = gz = np.float32(0.0)
        for lv in range(n_levels):
            rf = np.float32(res[lv])
            wx, wy, wz = _locate(x, n, res[lv], offsets[lv], lv < num_dense, mask, row)
            lx = ly = lz = np.float32(0.0)
            for k in range(8):
                t = np.float32(0.0)  # the corner's value along grad_out
                for f in range(n_feat):
                    t += table[row[k], f] * grad_out[n, lv * n_feat + f]
                bx, by, bz = k & 1, (k >> 1) & 1, (k >> 2) & 1
                sx, sy, sz = np.float32(2 * bx - 1), np.float32(2 * by - 1), np.float32(2 * bz - 1)
                lx += sx * wz[bz] * wy[by] * t
                ly += sy * wz[bz] * wx[bx] * t
                lz += sz * wy[by] * wx[bx] * t
            gx += rf * lx
            gy += rf * ly
            gz += rf * lz
        grad_x[n, 0] = gx
        grad_x[n, 1] = gy
        grad_x[n, 2] = gz


@njit(cache=True, nogil=True)
def _locate(x, n, r, offset, dense, mask, row):  # noqa: ANN001, ANN202
    """Point n's cell at resolution r: its 8 corner rows into `row`, and the (1 - f, f)
    trilinear weight pairs along x, y and z."""
    rf = np.float32(r)
    cx, fx = _cell(x[n, 0] * rf, r)
    cy, fy = _cell(x[n, 1] * rf, r)
    cz, fz = _cell(x[n, 2] * rf, r)
    _corner_rows(cx, cy, cz, r, offset, dense, mask, row)
    return (_ONE - fx, fx), (_ONE - fy, fy), (_ONE - fz, fz)


@njit(cache=True, nogil=True)
def _corner_rows(cx, cy, cz, r, offset, dense, mask, row) -> None:  # noqa: ANN001
    """Table rows of a cell's 8 corners (x fastest), dense-indexed or hashed."""
    if dense:
        s1 = r + 1
        s2 = s1 * s1
        base = cx + cy * s1 + cz * s2 + offset
        for k in range(8):
            row[k] = base + (k & 1) + ((k >> 1) & 1) * s1 + ((k >> 2) & 1) * s2
        return
    for k in range(8):
        hx = (cx + (k & 1)) & mask
        hy = ((cy + ((k >> 1) & 1)) * _P1) & mask
        hz = ((cz + ((k >> 2) & 1)) * _P2) & mask | offset
        row[k] = hz ^ (hy ^ hx)


@njit(cache=True, nogil=True)
def _popcount(word):  # noqa: ANN001
    """Set bits of a 64-bit word (SWAR)."""
    word = word - ((word >> np.uint64(1)) & np.uint64(0x5555555555555555))
    word = (word & np.uint64(0x3333333333333333)) + (
        (word >> np.uint64(2)) & np.uint64(0x3333333333333333)
    )
    word = (word + (word >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return np.int64((word * np.uint64(0x0101010101010101)) >> np.uint64(56))


@njit(cache=True, nogil=True)
def table_grad(rows, weights, grad_out, bitmap, rank, n_feat):  # noqa: ANN001
    """The table's gradient from the backward of `encode`: (sorted distinct rows, sums).

    rows, weights (N, L, 8); grad_out (N, L * F). bitmap (one bit per table row, all
    zero; left all zero again) and rank (one int64 per bitmap word) are scratch kept
    between calls. A row's place among the distinct rows is the set bits before it: the
    bits of the words before its word (rank) plus those below it in its word. Both arrays
    are small enough to stay in cache, unlike a per-row table.
    """
    n_points, n_levels = rows.shape[0], rows.shape[1]
    for n in range(n_points):
        for lv in range(n_levels):
            for k in range(8):
                r = rows[n, lv, k]
                bitmap[r >> 6] |= np.uint64(1) << np.uint64(r & 63)
    count = 0
    for word_index in range(bitmap.shape[0]):
        rank[word_index] = count
        word = bitmap[word_index]
        if word:
            count += _popcount(word)
    distinct = np.empty(count, dtype=np.int64)
    i = 0
    for word_index in range(bitmap.shape[0]):
        word = bitmap[word_index]
        while word:
            low = word & (~word + np.uint64(1))
            distinct[i] = (word_index << 6) + _DEBRUIJN_INDEX[(low * _DEBRUIJN) >> np.uint64(58)]
            i += 1
            word ^= low
    sums = np.zeros((count, n_feat), dtype=np.float32)
    for n in range(n_points):
        for lv in range(n_levels):
            for k in range(8):
                r = rows[n, lv, k]
                word_index = r >> 6
                below = bitmap[word_index] & ((np.uint64(1) << np.uint64(r & 63)) - np.uint64(1))
                s, w = rank[word_index] + _popcount(below), weights[n, lv, k]
                for f in range(n_feat):
                    sums[s, f] += w * grad_out[n, lv * n_feat + f]
    for i in range(count):
        bitmap[distinct[i] >> 6] = np.uint64(0)
    return distinct, sums


@njit(cache=True, nogil=True)
def adam_rows(param, moments, rows, grads, beta1, beta2, step_size, eps, weight_decay):  # noqa: ANN001
    """Adam on the given distinct rows of param (R, F), moments (R, 2, F), in place.

    As FieldAdam's PyTorch path: L2 weight decay into the gradient, m lerped toward g,
    v = beta2 v + (1 - beta2) g^2, p -= step_size m / (sqrt(v) + eps) (eps already scaled
    by the bias correction the step size folds in).
    """
    b1, b2 = np.float32(1.0 - beta1), np.float32(beta2)
    c2, lr = np.float32(1.0 - beta2), np.float32(step_size)
    e, wd = np.float32(eps), np.float32(weight_decay)
    for u in range(rows.shape[0]):
        r = rows[u]
        for f in range(param.shape[1]):
            g = grads[u, f]
            if wd != 0:
                g = g + wd * param[r, f]
            m = moments[r, 0, f]
            m = m + b1 * (g - m)
            v = moments[r, 1, f] * b2 + c2 * g * g
            moments[r, 0, f] = m
            moments[r, 1, f] = v
            param[r, f] = param[r, f] - lr * (m / (np.sqrt(v) + e))
