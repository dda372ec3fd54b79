"""Material colours: fixed for known materials, distinct fallbacks, ignore black, background white."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.materials import BACKGROUND, DEFAULT_MATERIALS
from neuralfeels_sem.core.palette import MATERIAL_COLOURS, class_colours, colorize

CLASSES = list(DEFAULT_MATERIALS)


def test_colorize_exact_colours() -> None:
    labels = np.array([[0, 1, 2], [3, -1, BACKGROUND]])
    rgb = colorize(labels, CLASSES)
    assert rgb.shape == (2, 3, 3) and rgb.dtype == np.uint8
    for index, name in enumerate(CLASSES):
        assert tuple(rgb.reshape(-1, 3)[index]) == MATERIAL_COLOURS[name]
    assert tuple(rgb[1, 1]) == (0, 0, 0)
    assert tuple(rgb[1, 2]) == (255, 255, 255)


def test_known_materials_keep_their_colour_in_any_order() -> None:
    a = class_colours(["wood", "plastic"])
    b = class_colours(["plastic", "wood"])
    np.testing.assert_array_equal(a[0], b[1])


def test_unknown_names_get_distinct_colours() -> None:
    names = ["plastic", "glass", "rubber", "paper", "stone"]
    colours = {tuple(c) for c in class_colours(names)}
    assert len(colours) == len(names)
    assert (0, 0, 0) not in colours and (255, 255, 255) not in colours


def test_many_classes_still_work() -> None:
    names = [f"m{i}" for i in range(20)]
    assert class_colours(names).shape == (20, 3)


@pytest.mark.parametrize("labels", [np.array([4]), np.array([-3]), np.array([0.5])])
def test_bad_labels_are_value_errors(labels: np.ndarray) -> None:
    with pytest.raises(ValueError):
        colorize(labels, CLASSES)
