"""A tensor stored as deflated byte planes: lossless, smaller where the high bytes repeat.

The bytes of each element are split into planes (byte 0 of every element, then byte 1,
...), and every plane but the lowest byte of a floating-point tensor is deflated (zlib):
the sign and exponent bytes of a float16 hash table, and the 8-bit moment codes of a
compact checkpoint, take few distinct values, while a float's lowest mantissa byte is
noise that deflate cannot shrink (skipping it saves the time). On the default run's
checkpoint this takes 35 MB of codes to about 28 MB (docs/usage.md).
"""

from __future__ import annotations

import zlib

import numpy as np
import torch
from torch import Tensor

# zlib level 1: nearly the ratio of level 6 on these planes at a fraction of the time.
DEFLATE_LEVEL = 1
_DTYPES = {
    "float16": torch.float16,
    "float32": torch.float32,
    "int8": torch.int8,
    "uint8": torch.uint8,
}


def pack_planes(values: Tensor) -> dict:
    """`values` (CPU, a dtype of _DTYPES) as {"dtype", "shape", "planes", "deflated"}."""
    name = str(values.dtype).removeprefix("torch.")
    if name not in _DTYPES:
        raise ValueError(f"pack_planes takes {sorted(_DTYPES)}, got {values.dtype}")
    width = values.element_size()
    raw = values.contiguous().view(-1).view(torch.uint8).numpy().reshape(-1, width)
    planes, deflated = [], []
    for byte in range(width):
        plane = np.ascontiguousarray(raw[:, byte])
        noise = values.is_floating_point() and byte == 0
        data = plane.tobytes() if noise else zlib.compress(plane.tobytes(), DEFLATE_LEVEL)
        planes.append(torch.frombuffer(bytearray(data), dtype=torch.uint8))
        deflated.append(not noise)
    return {"dtype": name, "shape": list(values.shape), "planes": planes, "deflated": deflated}


def unpack_planes(packed: dict) -> Tensor:
    """The tensor `pack_planes` stored."""
    dtype = _DTYPES[packed["dtype"]]
    width = torch.empty(0, dtype=dtype).element_size()
    count = int(np.prod(packed["shape"], dtype=np.int64))
    raw = np.empty((count, width), dtype=np.uint8)
    for byte, (plane, deflated) in enumerate(zip(packed["planes"], packed["deflated"])):
        data = plane.numpy().tobytes()
        raw[:, byte] = np.frombuffer(zlib.decompress(data) if deflated else data, dtype=np.uint8)
    return torch.from_numpy(raw.reshape(-1)).view(dtype).reshape(packed["shape"])


def packed_bytes(packed: dict) -> int:
    """Bytes the packed planes take (what they add to a checkpoint)."""
    return sum(plane.numel() for plane in packed["planes"])
