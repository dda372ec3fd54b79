"""Deterministic synthetic tactile data sets for classifier tests (no simulator needed).

Each class has its own texture (horizontal stripes, vertical stripes, checkerboard,
dots) pressed into a smooth per-sensor background, with jittered frequency and phase,
so a small network can tell them apart from a handful of images.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS

SENSORS = ("index", "middle", "ring", "thumb")
CLASSES = list(DEFAULT_MATERIALS)


def background(sensor_index: int) -> np.ndarray:
    """Smooth DIGIT-like frame, different per sensor."""
    v, u = np.mgrid[0:DIGIT_HEIGHT, 0:DIGIT_WIDTH].astype(np.float32)
    base = np.array([70.0, 85.0, 95.0]) + 8 * sensor_index
    img = np.empty((DIGIT_HEIGHT, DIGIT_WIDTH, 3), np.float32)
    img[:] = base
    img[..., 0] += 60 * np.exp(-(((u - 30) / 80) ** 2))
    img[..., 1] += 50 * np.exp(-(((u - 210) / 80) ** 2))
    img[..., 2] += 40 * np.exp(-(((v - 320) / 90) ** 2))
    return np.clip(img, 0, 255).astype(np.uint8)


def texture(label: int, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float texture in [-1, 1] for class `label` with random frequency and phase."""
    v, u = np.mgrid[0:DIGIT_HEIGHT, 0:DIGIT_WIDTH].astype(np.float32)
    period = rng.uniform(14, 22)
    phase = rng.uniform(0, 2 * np.pi)
    if label == 0:
        return np.sin(2 * np.pi * v / period + phase)
    if label == 1:
        return np.sin(2 * np.pi * u / period + phase)
    if label == 2:
        return np.sign(
            np.sin(2 * np.pi * u / period + phase) * np.sin(2 * np.pi * v / period + phase)
        )
    return np.cos(2 * np.pi * u / period + phase) * np.cos(2 * np.pi * v / period + phase) > 0.6


def pressed(sensor_index: int, label: int, rng: np.random.Generator) -> np.ndarray:
    """A contact frame: the class texture inside an elliptical contact patch."""
    img = background(sensor_index).astype(np.float32)
    v, u = np.mgrid[0:DIGIT_HEIGHT, 0:DIGIT_WIDTH].astype(np.float32)
    cy, cx = rng.uniform(120, 200), rng.uniform(90, 150)
    patch = np.exp(-(((u - cx) / 70) ** 2 + ((v - cy) / 90) ** 2))
    tex = texture(label, rng).astype(np.float32)
    img += (patch * (40 + 50 * tex))[..., None]
    img += rng.normal(0, 2, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def make_dataset(
    root: Path,
    per_group: int = 6,
    sensors: tuple[str, ...] = SENSORS,
    classes: list[str] = CLASSES,
    seed: int = 0,
    with_backgrounds: bool = True,
) -> Path:
    """Write `<root>/<sensor>/<class>/<id>.png` (and `_backgrounds/<sensor>.png`); return root."""
    rng = np.random.default_rng(seed)
    for s, sensor in enumerate(sensors):
        for c, name in enumerate(classes):
            folder = root / sensor / name
            folder.mkdir(parents=True, exist_ok=True)
            for i in range(per_group):
                cv2.imwrite(str(folder / f"{i:04d}.png"), pressed(s, c, rng)[..., ::-1])
        if with_backgrounds:
            (root / "_backgrounds").mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(root / "_backgrounds" / f"{sensor}.png"), background(s)[..., ::-1])
    return root
