"""The material classes of the default config, in the shipped classifier's output order.

The one place they are written out: the root config's `materials` defaults to this list
(configs/root.py; conf/config.yaml does not repeat it), and code that needs a class list
without a config (benchmarks, the simulator's tactile renderer, MapperConfig's class
count) uses it. A run's classes are always `cfg.materials`.
"""

from __future__ import annotations

DEFAULT_MATERIALS: list[str] = ["plastic", "metal", "fabric", "wood"]  # copy before changing
