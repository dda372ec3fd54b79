"""A compact U-Net that reads a DIGIT frame against its no-contact background.

Input: the difference image minus background, area-downsampled to `input_size` (rows,
columns) and scaled to about unit range. The simulated gel adds its shading to the
background, so the difference carries everything a press changes; leaving the raw image
out keeps a brightness or LED-colour change of the background from looking like a press.

Output, at half the input resolution and upsampled bilinearly to the full 320 x 240
frame: a contact logit and the press depth into the gel in millimetres (softplus, so
never negative). `to_depth` turns them into the simulator's convention (metres along the
sensor's +z, 0 off-contact).
"""

from __future__ import annotations

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH, GEL_DISTANCE_M, MAX_PENETRATION_M

ARCH = "tactile-depth-unet"
INPUT_SCALE = 32.0  # grey levels that map to 1.0 at the input


def conv_block(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class TactileDepthNet(nn.Module):
    """Encoder of four scales (strides 2, 4, 8, 16) and an additive decoder back to stride 2.

    `width` channels at stride 2, doubling per scale up to 4 x width; skips are added
    after a 1x1 projection rather than concatenated, which keeps the CPU cost low.
    """

    def __init__(self, width: int = 16) -> None:
        super().__init__()
        if width < 4:
            raise ValueError(f"width={width} must be >= 4")
        c1, c2, c3 = width, 2 * width, 4 * width
        self.width = width
        self.enc1 = nn.Sequential(conv_block(3, c1, 2), conv_block(c1, c1))
        self.enc2 = nn.Sequential(conv_block(c1, c2, 2), conv_block(c2, c2))
        self.enc3 = nn.Sequential(conv_block(c2, c3, 2), conv_block(c3, c3))
        # The deepest scale sees most of the gel: a flat press changes little inside its
        # outline, so the mask there is inferred from the rim around it.
        self.enc4 = nn.Sequential(conv_block(c3, c3, 2), conv_block(c3, c3))
        self.lat3 = nn.Conv2d(c3, c3, 1)
        self.dec3 = conv_block(c3, c3)
        self.lat2 = nn.Conv2d(c3, c2, 1)
        self.dec2 = conv_block(c2, c2)
        self.lat1 = nn.Conv2d(c2, c1, 1)
        self.dec1 = conv_block(c1, c1)
        self.head = nn.Conv2d(c1, 2, 1)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, 3, H, W) -> contact logits and press depth in mm, both (N, H/2, W/2)."""
        s1 = self.enc1(x)
        s2 = self.enc2(s1)
        s3 = self.enc3(s2)
        s4 = self.enc4(s3)
        d3 = self.dec3(s3 + self.lat3(_up(s4, s3)))
        d2 = self.dec2(s2 + self.lat2(_up(d3, s2)))
        d1 = self.dec1(s1 + self.lat1(_up(d2, s1)))
        out = self.head(d1)
        return out[:, 0], F.softplus(out[:, 1])


def _up(x: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    return F.interpolate(x, size=like.shape[-2:], mode="bilinear", align_corners=False)


def build_model(width: int) -> TactileDepthNet:
    return TactileDepthNet(width)


def preprocess(
    images: np.ndarray, backgrounds: np.ndarray, input_size: tuple[int, int]
) -> torch.Tensor:
    """(N, 320, 240, 3) uint8 frames and their backgrounds -> (N, 3, rows, cols) float32."""
    if (
        images.shape != backgrounds.shape
        or images.ndim != 4
        or images.shape[1:]
        != (
            DIGIT_HEIGHT,
            DIGIT_WIDTH,
            3,
        )
    ):
        raise ValueError(
            f"need (N, {DIGIT_HEIGHT}, {DIGIT_WIDTH}, 3) images and backgrounds, got "
            f"{images.shape} and {backgrounds.shape}"
        )
    rows, cols = input_size
    diff = images.astype(np.float32) - backgrounds.astype(np.float32)
    small = [cv2.resize(d, (cols, rows), interpolation=cv2.INTER_AREA) for d in diff]
    batch = np.stack(small).transpose(0, 3, 1, 2) / np.float32(INPUT_SCALE)
    return torch.from_numpy(np.ascontiguousarray(batch))


def full_resolution(maps: torch.Tensor) -> torch.Tensor:
    """(N, h, w) network maps -> (N, 320, 240), bilinear."""
    return F.interpolate(
        maps[:, None], size=(DIGIT_HEIGHT, DIGIT_WIDTH), mode="bilinear", align_corners=False
    )[:, 0]


def to_depth(logits: torch.Tensor, press_mm: torch.Tensor, min_contact_px: int) -> np.ndarray:
    """Full-resolution logits and press depth -> (N, 320, 240) float32 metres, 0 off-contact.

    A frame whose contact covers fewer than `min_contact_px` pixels counts as no contact
    (specks of noise, not a touch).
    """
    contact = (logits > 0).cpu().numpy()
    press_m = np.clip(press_mm.cpu().numpy() / 1000.0, 0.0, MAX_PENETRATION_M)
    small = contact.reshape(len(contact), -1).sum(axis=1) < min_contact_px
    contact[small] = False
    return np.where(contact, GEL_DISTANCE_M - press_m, 0.0).astype(np.float32)
