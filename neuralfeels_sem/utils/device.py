"""Pick the torch device (`auto`: CUDA when present, else CPU) and the CPU thread count
(torch's and numpy's BLAS).

`threads` (a root config key, resolved once at start-up by tasks/runner.py):
- `auto`: OMP_NUM_THREADS when set, else 1 thread. Measured on the project's 2-core
  machines (docs/field_and_mapper.md#cost): a mapper step with two torch threads took
  0.8 s of CPU instead of 0.09 s with one while other jobs ran (load 15-19: OpenMP's
  waiting threads spin on cores that other processes need), for a gain of at most about
  1.3x on an idle machine. One thread is the setting that is never badly wrong.
- `N`: exactly N torch threads (for an idle machine, or more cores).
"""

import os

from neuralfeels_sem.core.errors import ConfigError

THREADS_AUTO = "auto"


def resolve_device(name: str = "auto") -> "torch.device":  # noqa: F821
    import torch

    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={name} but no CUDA GPU is visible; use device=cpu or device=auto"
        )
    return torch.device(name)


def resolve_threads(setting: str | int = THREADS_AUTO) -> int:
    """The torch CPU thread count a `threads` setting asks for (see the module docstring)."""
    text = str(setting).strip()
    if text == THREADS_AUTO:
        env = os.environ.get("OMP_NUM_THREADS", "")
        return int(env) if env.isdigit() and int(env) > 0 else 1
    if not text.isdigit() or int(text) < 1:
        raise ConfigError(f"threads={setting!r}: use auto or a whole number >= 1")
    return int(text)


def set_threads(setting: str | int = THREADS_AUTO) -> int:
    """Set torch's CPU threads, and numpy's BLAS threads to the same count, from a `threads`
    setting once, at start-up; returns the count.

    numpy's OpenBLAS starts one thread per core of its own, outside torch's setting: on a
    busy 2-core machine its spinning threads made the (N, 3) x (3, 3) point transforms of
    every camera frame about 20 times more expensive in CPU than one thread does.
    """
    import torch
    from threadpoolctl import threadpool_limits

    threads = resolve_threads(setting)
    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)
    threadpool_limits(limits=threads, user_api="blas")
    return threads
