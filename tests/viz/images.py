"""Check that a written file is a real, non-trivial PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image


def assert_png(path: Path, min_width: int = 200, min_height: int = 150) -> np.ndarray:
    assert path.exists(), path
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    with Image.open(path) as image:
        image.verify()
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"))
    height, width = pixels.shape[:2]
    assert width >= min_width and height >= min_height, (width, height)
    assert pixels.reshape(-1, 3).std(axis=0).max() > 5, f"{path} is blank"
    return pixels
