"""Row gathers and scatters of a 2-D table, each row moved as one machine word.

The hash table's rows are 2 float32 (8 bytes) and FieldAdam's moment rows 2 x 2 float32
(16 bytes). torch's index_select / index_copy_ on a (rows, k) float tensor copy k
elements per row through a generic strided loop; viewed as a 1-D tensor of one 8- or
16-byte element per row (int64 or complex128, whichever matches the row size) the same
copy is a single contiguous-element gather, 2-3x faster on CPU for random rows. Only
bytes move, so the results are bit-identical; rows of any other size, or tensors that
are not contiguous, take torch's ordinary path.
"""

from __future__ import annotations

import torch
from torch import Tensor

# Row size in bytes -> a dtype of exactly that size (a row becomes one element).
_WORD_DTYPES = {8: torch.int64, 16: torch.complex128}


def _as_words(t: Tensor) -> Tensor | None:
    """t (rows, ...) viewed as (rows,) one-element-per-row words, or None when it cannot be."""
    if t.ndim < 2 or not t.is_contiguous() or t.is_complex() or t.shape[0] == 0:
        return None
    row_bytes = t[0].numel() * t.element_size()
    dtype = _WORD_DTYPES.get(row_bytes)
    if dtype is None or t.storage_offset() * t.element_size() % row_bytes:
        return None
    return t.reshape(t.shape[0], -1).view(dtype).view(t.shape[0])


def gather_rows(table: Tensor, idx: Tensor) -> Tensor:
    """table.index_select(0, idx), moving each row as one word where the row size allows."""
    words = _as_words(table)
    if words is None:
        return table.index_select(0, idx)
    out = words.index_select(0, idx)
    return out.view(table.dtype).view(idx.shape[0], *table.shape[1:])


def copy_rows_(table: Tensor, idx: Tensor, values: Tensor) -> Tensor:
    """table.index_copy_(0, idx, values) in place, row by word where the row size allows."""
    words, value_words = _as_words(table), _as_words(values.contiguous())
    if words is None or value_words is None or values.dtype != table.dtype:
        return table.index_copy_(0, idx, values)
    words.index_copy_(0, idx, value_words)
    return table
