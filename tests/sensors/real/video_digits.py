"""Write raw DIGIT-like landscape frames to a video file that DigitCamera reads through OpenCV."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def digit_like_frames(count: int, seed: int = 0) -> list[np.ndarray]:
    """Smooth landscape BGR frames (240 x 320) with a moving dark blob, like a press on the gel."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:240, 0:320]
    base = np.stack([90 + 60 * xx / 320, 120 + 50 * yy / 240, 150 - 40 * xx / 320], axis=-1)
    frames = []
    for k in range(count):
        cx, cy = 60 + 8 * k, 120 + rng.integers(-5, 5)
        blob = 60 * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 300.0)
        frames.append(np.clip(base - blob[..., None], 0, 255).astype(np.uint8))
    return frames


def write_video(path: Path, frames: list[np.ndarray], fps: float = 30.0) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (320, 240))
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path
