"""The no-contact DIGIT frame: a procedural one (default) or a real one loaded from disk.

A real DIGIT's empty frame shows the three LEDs as soft coloured glows through the gel:
red from one side, green from the other, blue from the bottom edge, over a dark
blue-grey base with vignetting. The procedural frame copies that layout; `seed` jitters
glow positions and strengths so each simulated finger gets its own background, as
real sensors do.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.hand import FINGERS

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


def finger_seed(seed: int, finger: str) -> int:
    """Renderer seed of one finger's DIGIT (its background and noise stream)."""
    return seed + FINGERS.index(finger)


def procedural_background(
    seed: int = 0, height: int = DIGIT_HEIGHT, width: int = DIGIT_WIDTH
) -> np.ndarray:
    """Deterministic DIGIT-like empty frame, (height, width, 3) uint8 RGB."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    x, y = u / width, v / height  # 0..1 across columns / rows
    img = np.empty((height, width, 3), np.float32)
    img[:] = np.array([62.0, 78.0, 88.0]) + rng.uniform(-6, 6, 3)
    # Three LED glows: (centre x, centre y, sigma x, sigma y, RGB strength).
    glows = [
        (0.12, 0.50, 0.30, 0.35, (125.0, 5.0, 25.0)),  # red, one side
        (0.92, 0.55, 0.28, 0.35, (5.0, 85.0, 10.0)),  # green, other side
        (0.45, 1.02, 0.30, 0.18, (5.0, 20.0, 90.0)),  # blue, bottom edge
    ]
    for cx, cy, sx, sy, colour in glows:
        cx, cy = cx + rng.uniform(-0.06, 0.06), cy + rng.uniform(-0.06, 0.06)
        gain = rng.uniform(0.8, 1.15)
        blob = np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))
        img += gain * blob[..., None] * np.asarray(colour, np.float32)
    # Low-frequency blotches (gel thickness and paint are never perfectly uniform).
    blotch = cv2.resize(
        rng.normal(0, 1, (6, 5, 3)).astype(np.float32),
        (width, height),
        interpolation=cv2.INTER_CUBIC,
    )
    img += 6.0 * blotch
    # Vignetting: the gel's corners are darker.
    r2 = ((x - 0.5) / 0.55) ** 2 + ((y - 0.5) / 0.6) ** 2
    img *= (1.0 - 0.35 * np.clip(r2, 0, 1.5))[..., None]
    # Fixed pixel pattern of the sensor, then a slight blur like the real camera optics.
    img += rng.normal(0, 1.5, img.shape).astype(np.float32)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    return np.clip(img, 0, 255).astype(np.uint8)


def load_background(
    path: str | Path, height: int = DIGIT_HEIGHT, width: int = DIGIT_WIDTH
) -> np.ndarray:
    """A real empty DIGIT frame from an image file, RGB, resized to (height, width) if needed."""
    path = Path(path).expanduser()
    if not path.is_file():
        raise DataError(
            f"DIGIT background {path} does not exist; pass an image file, e.g. one from ../shared/data/digit_real/backgrounds"
        )
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise DataError(
            f"DIGIT background {path} is not a readable image; use a PNG or JPG of an empty DIGIT frame"
        )
    if bgr.shape[:2] == (width, height) and width != height:
        bgr = np.ascontiguousarray(np.rot90(bgr))  # landscape capture of a portrait sensor
    if bgr.shape[:2] != (height, width):
        bgr = cv2.resize(bgr, (width, height), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def resolve_background(
    background: np.ndarray | str | Path | None,
    seed: int = 0,
    height: int = DIGIT_HEIGHT,
    width: int = DIGIT_WIDTH,
) -> np.ndarray:
    """None -> procedural(seed); a path -> loaded file (a folder picks its seed-th image); an array -> checked copy."""
    if background is None:
        return procedural_background(seed, height, width)
    if isinstance(background, np.ndarray):
        if background.shape != (height, width, 3) or background.dtype != np.uint8:
            raise ValueError(
                f"background must be ({height}, {width}, 3) uint8, got {background.shape} {background.dtype}"
            )
        return background.copy()
    path = Path(background).expanduser()
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
        if not files:
            raise DataError(
                f"DIGIT background folder {path} holds no PNG/JPG images; point it at a folder of empty frames"
            )
        path = files[seed % len(files)]
    return load_background(path, height, width)
