"""Repeatable runs: one seed for Python, NumPy and torch."""

import os
import random
import sys

import numpy as np


def seed_everything(seed: int, deterministic: bool = True) -> None:
    """Seed every RNG the project uses; on CPU this makes runs bit-repeatable."""
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    random.seed(seed)
    np.random.seed(seed % 2**32)
    os.environ["PYTHONHASHSEED"] = str(seed)
    import torch

    torch.manual_seed(seed)
    if deterministic:
        _deterministic_algorithms()


def _deterministic_algorithms() -> None:
    """torch.use_deterministic_algorithms(True, warn_only=True) without its import of the
    compiler: the public call also sets torch._inductor's flag, importing torch._inductor and
    torch._dynamo (1.2 s on a laptop CPU, in every run and worker) for code that is never
    compiled here. Where the compiler is already loaded, its flag is set as well."""
    import torch

    torch._C._set_deterministic_algorithms(True, warn_only=True)
    inductor_config = sys.modules.get("torch._inductor.config")
    if inductor_config is not None:
        inductor_config.deterministic = True
