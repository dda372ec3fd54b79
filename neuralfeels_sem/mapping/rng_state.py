"""Random-number states a resumed run must restore to continue bit for bit.

The mapper draws its samples from its own torch.Generator; torch's, Python's and NumPy's
global generators are saved too (a classifier or a sensor may draw from them). Tensors and
plain values only, so a checkpoint loads with torch.load(weights_only=True).
"""

from __future__ import annotations

import random

import numpy as np
import torch


def capture_rng(generator: torch.Generator) -> dict:
    np_state = np.random.get_state()
    return {
        "mapper": generator.get_state(),
        "torch": torch.get_rng_state(),
        "python": random.getstate(),
        "numpy": {
            "keys": torch.from_numpy(np_state[1].astype(np.int64)),
            "pos": int(np_state[2]),
            "has_gauss": int(np_state[3]),
            "cached_gaussian": float(np_state[4]),
        },
    }


def restore_rng(state: dict, generator: torch.Generator) -> None:
    generator.set_state(state["mapper"])
    torch.set_rng_state(state["torch"])
    random.setstate(state["python"])
    npr = state["numpy"]
    np.random.set_state(
        (
            "MT19937",
            npr["keys"].numpy().astype(np.uint32),
            npr["pos"],
            npr["has_gauss"],
            npr["cached_gaussian"],
        )
    )
