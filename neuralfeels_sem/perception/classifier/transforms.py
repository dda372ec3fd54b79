"""Image preprocessing shared by training and inference, and training augmentation.

Both paths resize with the same function (OpenCV area interpolation to a square
input, as the DIGIT's 320x240 frame is squashed in the paper's recipe) and normalise
with the mean/std stored in the checkpoint, so a trained model sees the same pixels
at inference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import torch
import torch.nn.functional as F

from neuralfeels_sem.perception.contact import channel_sum

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def resize_image(image: np.ndarray, size: int) -> np.ndarray:
    """(H, W, 3) uint8 -> (size, size, 3) uint8."""
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 image, got {image.shape} {image.dtype}")
    if image.shape[:2] == (size, size):
        return image
    return cv2.resize(image, (size, size), interpolation=cv2.INTER_AREA)


def contact_crop(
    image: np.ndarray, background: np.ndarray | None, crop_px: int, threshold: float = 20.0
) -> np.ndarray:
    """Square `crop_px` window around the contact, at the sensor's native resolution.

    Centred on the centroid of the (blurred) difference to the no-contact background; the
    frame centre without a background or contact. Squashing a whole 320x240 frame into a
    small input averages the micro-texture away; a crop keeps it.
    """
    h, w = image.shape[:2]
    crop = min(int(crop_px), h, w)
    cy, cx = h / 2.0, w / 2.0
    if background is not None and background.shape == image.shape:
        # int16: three channels of at most 255 each add up exactly
        diff = channel_sum(np.abs(image.astype(np.int16) - background.astype(np.int16)))
        weight = np.clip(cv2.blur(diff.astype(np.float32), (9, 9)) - threshold, 0.0, None)
        total = float(weight.sum())
        if total > 0:
            cy = float(weight.sum(axis=1) @ np.arange(h)) / total
            cx = float(weight.sum(axis=0) @ np.arange(w)) / total
    y0 = int(np.clip(round(cy - crop / 2.0), 0, h - crop))
    x0 = int(np.clip(round(cx - crop / 2.0), 0, w - crop))
    return image[y0 : y0 + crop, x0 : x0 + crop]


def preprocess(
    image: np.ndarray, size: int, crop_px: int | None = None, background: np.ndarray | None = None
) -> np.ndarray:
    """The model's input pixels: optional contact crop, then resize to size x size."""
    if crop_px:
        image = contact_crop(image, background, crop_px)
    return resize_image(np.ascontiguousarray(image), size)


def resize_batch(images: np.ndarray | Sequence[np.ndarray], size: int) -> np.ndarray:
    """(B, H, W, 3) uint8 (or a list of images) -> (B, size, size, 3) uint8."""
    return np.stack([resize_image(np.asarray(im), size) for im in images])


def to_tensor(images: np.ndarray | torch.Tensor) -> torch.Tensor:
    """(B, S, S, 3) uint8 -> (B, 3, S, S) float32 in [0, 1]."""
    if isinstance(images, np.ndarray):
        images = torch.from_numpy(np.ascontiguousarray(images))
    if images.ndim != 4 or images.shape[-1] != 3:
        raise ValueError(f"expected (B, S, S, 3) images, got {tuple(images.shape)}")
    return images.permute(0, 3, 1, 2).float().div_(255.0)


def normalize(x: torch.Tensor, mean: Sequence[float], std: Sequence[float]) -> torch.Tensor:
    m = torch.as_tensor(mean, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    s = torch.as_tensor(std, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    return (x - m) / s


def augment(
    x: torch.Tensor,
    generator: torch.Generator,
    rotation_deg: float = 30.0,
    brightness: float = 0.2,
    contrast: float = 0.2,
    color_gain: float = 0.1,
) -> torch.Tensor:
    """Random rotation and lighting change of (B, 3, S, S) images in [0, 1].

    Lighting: a global brightness scale, a contrast scale about the image mean and a
    per-channel gain (the DIGIT's three LEDs drift independently between sensors).
    Random numbers come from `generator` (on the CPU) so a resumed run repeats them.
    """
    b = x.shape[0]

    def uniform(*shape: int, scale: float) -> torch.Tensor:
        return ((torch.rand(*shape, generator=generator) * 2 - 1) * scale).to(x.device)

    if rotation_deg > 0:
        angle = uniform(b, scale=math.radians(rotation_deg))
        cos, sin = torch.cos(angle), torch.sin(angle)
        zeros = torch.zeros_like(cos)
        theta = torch.stack(
            [torch.stack([cos, -sin, zeros], 1), torch.stack([sin, cos, zeros], 1)], 1
        )
        grid = F.affine_grid(theta, list(x.shape), align_corners=False)
        x = F.grid_sample(x, grid, mode="bilinear", padding_mode="reflection", align_corners=False)
        x = x.contiguous(memory_format=torch.channels_last)  # the model's layout (model.py)
    if contrast > 0:
        mean = x.mean(dim=(1, 2, 3), keepdim=True)
        x = (x - mean) * (1 + uniform(b, 1, 1, 1, scale=contrast)) + mean
    if brightness > 0:
        x = x * (1 + uniform(b, 1, 1, 1, scale=brightness))
    if color_gain > 0:
        x = x * (1 + uniform(b, 3, 1, 1, scale=color_gain))
    return x.clamp_(0.0, 1.0)
