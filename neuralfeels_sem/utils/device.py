"""Pick the torch device: `auto` means CUDA when present, else all CPU cores."""

import os

from neuralfeels_sem.core.errors import ConfigError


def resolve_device(name: str = "auto") -> "torch.device":  # noqa: F821
    import torch

    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={name} but no CUDA GPU is visible; use device=cpu or device=auto"
        )
    if name == "cpu" and "OMP_NUM_THREADS" not in os.environ:
        # All cores by default; an explicit OMP_NUM_THREADS (e.g. on a shared machine) wins.
        torch.set_num_threads(max(1, os.cpu_count() or 1))
    return torch.device(name)
