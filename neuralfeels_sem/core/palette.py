"""Material colours shared by every picture and the coloured mesh (RGB uint8).

Label conventions: class indices 0..C-1 index `class_names`; IGNORE (-1) is outside the
regions of interest (black, as in the paper's maps); BACKGROUND (-2) is no object (white).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from neuralfeels_sem.core.materials import BACKGROUND

MATERIAL_COLOURS: dict[str, tuple[int, int, int]] = {
    "plastic": (52, 120, 220),  # blue
    "metal": (160, 164, 172),  # grey
    "fabric": (220, 60, 60),  # red
    "wood": (150, 100, 45),  # brown
}
# For class names without a fixed colour, in order of first use (colour-blind friendly set).
FALLBACK_COLOURS: tuple[tuple[int, int, int], ...] = (
    (0, 158, 115),
    (230, 159, 0),
    (204, 121, 167),
    (86, 180, 233),
    (240, 228, 66),
    (120, 60, 160),
    (0, 114, 178),
    (213, 94, 0),
)
IGNORE_COLOUR = (0, 0, 0)
BACKGROUND_COLOUR = (255, 255, 255)


def class_colours(class_names: Sequence[str]) -> np.ndarray:
    """(C, 3) uint8 colour of each class, fixed for known materials."""
    colours, spare = [], iter(FALLBACK_COLOURS * (1 + len(class_names) // len(FALLBACK_COLOURS)))
    for name in class_names:
        colours.append(MATERIAL_COLOURS.get(name.lower()) or next(spare))
    return np.asarray(colours, dtype=np.uint8).reshape(-1, 3)


def colorize(labels: np.ndarray, class_names: Sequence[str]) -> np.ndarray:
    """Integer labels of any shape -> (..., 3) uint8 RGB; IGNORE black, BACKGROUND white."""
    labels = np.asarray(labels)
    if not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must be integers, got {labels.dtype}")
    num = len(class_names)
    bad = (labels >= num) | (labels < BACKGROUND)
    if bad.any():
        raise ValueError(f"labels outside {BACKGROUND}..{num - 1}: {np.unique(labels[bad])[:5]}")
    table = np.concatenate(
        [np.array([BACKGROUND_COLOUR, IGNORE_COLOUR], dtype=np.uint8), class_colours(class_names)]
    )
    return table[labels.astype(np.int64) - BACKGROUND]
