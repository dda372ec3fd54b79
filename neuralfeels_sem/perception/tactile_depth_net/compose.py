"""Training frames from rendered shading: background + change + noise, as the renderer does.

A simulated DIGIT frame is its no-contact background plus the pressed gel's shading plus
pixel noise, clipped to 0..255 (sim/tactile_renderer.py). Composing the same sum over a
pool of backgrounds turns one render into frames of many sensors. Two things a rig adds
are drawn too: the stored background is itself a noisy capture (half of the frames), and
the LEDs and camera drift between that capture and the touch (a per-channel gain and
offset, half of the frames), which the network must not take for a press.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Augmentation:
    """Ranges of the drawn noise and drift; defaults: TrainTactileDepthTaskConfig."""

    max_noise_std: float  # grey levels; each frame draws its std in [0, max]
    max_gain_drift: float  # relative, per channel
    max_offset_drift: float  # grey levels, per channel


def compose_frames(
    change: np.ndarray,
    backgrounds: np.ndarray,
    rng: np.random.Generator,
    augmentation: Augmentation,
) -> tuple[np.ndarray, np.ndarray]:
    """(N, H, W, 3) shading changes over (N, H, W, 3) uint8 backgrounds -> (frames, the
    backgrounds the network is given), both uint8."""
    if change.shape != backgrounds.shape:
        raise ValueError(f"change {change.shape} and backgrounds {backgrounds.shape} differ")
    n = len(change)
    bg = backgrounds.astype(np.float32)
    drifting = rng.uniform(size=(n, 1, 1, 1)) < 0.5
    gain = 1.0 + drifting * rng.uniform(-1, 1, (n, 1, 1, 3)) * augmentation.max_gain_drift
    offset = drifting * rng.uniform(-1, 1, (n, 1, 1, 3)) * augmentation.max_offset_drift
    std = rng.uniform(0.0, augmentation.max_noise_std, (n, 1, 1, 1)).astype(np.float32)
    noise = rng.standard_normal(bg.shape, dtype=np.float32) * std
    frames = bg * gain.astype(np.float32) + offset.astype(np.float32) + change + noise
    noisy_capture = rng.uniform(size=(n, 1, 1, 1)) < 0.5
    given = bg + noisy_capture * rng.standard_normal(bg.shape, dtype=np.float32) * std
    return _to_uint8(frames), _to_uint8(given)


def _to_uint8(image: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
