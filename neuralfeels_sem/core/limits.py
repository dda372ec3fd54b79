"""Bounds on numbers a user sets: beyond these a run would never end or a library fails.

Config schemas call these from `__post_init__`; tasks/preflight.py checks what depends on
the machine (memory) or on files (mesh size) before any heavy set-up.
"""

from __future__ import annotations

import math

# A sensor or recording longer than a day is a typo (1e12), not an experiment.
MAX_DURATION_S = 24 * 3600.0
# Frames per second: the rig's streams run at 90 Hz at most (DIGIT 60, RealSense 90).
MAX_RATE_HZ = 1000.0
# numpy's legacy seed and PYTHONHASHSEED take 0..2^32-1 (torch takes more).
MAX_SEED = 2**32 - 1
# MuJoCo refuses meshes with more faces than this when it compiles the scene.
MUJOCO_MAX_FACES = 200_000


def check_duration(key: str, value: float | None) -> None:
    """ValueError naming `key` unless `value` is None or finite, > 0 and <= MAX_DURATION_S."""
    if value is None:
        return
    if not math.isfinite(value) or not 0 < value <= MAX_DURATION_S:
        raise ValueError(
            f"{key}={value} must be a finite number of seconds in (0, {MAX_DURATION_S:.0f}] (24 h)"
        )


def check_rate(key: str, value: float) -> None:
    """ValueError naming `key` unless `value` is finite, > 0 and <= MAX_RATE_HZ."""
    if not math.isfinite(value) or not 0 < value <= MAX_RATE_HZ:
        raise ValueError(f"{key}={value} must be a finite rate in (0, {MAX_RATE_HZ:.0f}] Hz")


def check_seed(value: int) -> None:
    """ValueError unless 0 <= seed <= MAX_SEED."""
    if value < 0:
        raise ValueError(f"seed={value} must be >= 0")
    if value > MAX_SEED:
        raise ValueError(f"seed={value} must be <= {MAX_SEED} (2^32 - 1, numpy's seed range)")
