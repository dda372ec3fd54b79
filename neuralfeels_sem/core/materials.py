"""The material classes of the default config and the label values outside them.

DEFAULT_MATERIALS, in the shipped classifier's output order, is the one place the classes
are written out: the root config's `materials` defaults to this list (configs/root.py;
conf/config.yaml does not repeat it), and code that needs a class list without a config
(benchmarks, the simulator's tactile renderer, MapperConfig's class count, tests) uses it.
A run's classes are always `cfg.materials`.

Labels: class indices 0..C-1 index the class names; IGNORE (-1) marks object faces outside
the regions of interest (black in the paper's maps), BACKGROUND (-2) pixels where no object
is seen (white in pictures).
"""

from __future__ import annotations

DEFAULT_MATERIALS: list[str] = ["plastic", "metal", "fabric", "wood"]  # copy before changing
IGNORE = -1
BACKGROUND = -2
