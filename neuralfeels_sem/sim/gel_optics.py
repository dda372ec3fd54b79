"""Gel optics of the simulated DIGIT, in numpy: indentation, elastomer smoothing, LED shading.

The gel is a height field seen head-on, so Lambertian + Blinn-Phong on its normals is
exact for that model and much cheaper than rendering a deformed gel mesh. Each step
works on a crop of the image around the contact (see DigitRenderer._shade).
"""

from __future__ import annotations

import cv2
import numpy as np

from neuralfeels_sem.core.digit import (
    DIGIT_HEIGHT,
    DIGIT_INTRINSICS,
    DIGIT_WIDTH,
    GEL_DISTANCE_M,
    GEL_WIDTH_M,
    MAX_PENETRATION_M,
)
from neuralfeels_sem.sim.textures import MicroTexture

MAX_RELIEF_M = 0.1e-3  # above every texture's highest relief (fabric threads + fuzz: ~60 um)
PIXEL_M = GEL_WIDTH_M / DIGIT_WIDTH  # gel-plane size of one pixel (75 um)
SOFT_REACH_M = (
    0.35e-3  # how much further a fully compliant surface (fibres, fuzz) reaches into the gel
)
# LEDs: direction from the gel toward each light in the sensor frame (+x = image right,
# +y = image down, -z = back toward the camera) and its RGB colour.
_LIGHT_DIRS = np.array([[-1.0, -0.15, -0.55], [1.0, 0.1, -0.55], [0.05, 1.0, -0.55]], np.float32)
_LIGHT_DIRS /= np.linalg.norm(_LIGHT_DIRS, axis=1, keepdims=True)
_LIGHT_RGB = np.array([[1.0, 0.12, 0.15], [0.1, 1.0, 0.15], [0.12, 0.2, 1.0]], np.float32)
# Blinn-Phong half vectors between each light and the view direction (-z, toward the camera).
_HALF_DIRS = _LIGHT_DIRS + np.array([0.0, 0.0, -1.0], np.float32)
_HALF_DIRS /= np.linalg.norm(_HALF_DIRS, axis=1, keepdims=True)


def _pow32(x: np.ndarray) -> np.ndarray:
    """x ** 32 by repeated squaring (much faster than a float power)."""
    for _ in range(5):
        x = x * x
    return x


def contact_crop(near: np.ndarray, pad: int) -> tuple[int, int, int, int]:
    """Rows r0:r1 and columns c0:c1 of the image around the `near` pixels, `pad` wider."""
    rows, cols = np.nonzero(near)
    r0, r1 = max(rows.min() - pad, 0), min(rows.max() + pad + 1, DIGIT_HEIGHT)
    c0, c1 = max(cols.min() - pad, 0), min(cols.max() + pad + 1, DIGIT_WIDTH)
    return r0, r1, c0, c1


def object_points(
    v: np.ndarray, u: np.ndarray, z: np.ndarray, r0: int, c0: int, object_T_sensor: np.ndarray
) -> np.ndarray:
    """Object-frame 3D points (float32) under crop pixels (v, u) at depth z along +z."""
    uf, vf = u.astype(np.float32), v.astype(np.float32)
    k = DIGIT_INTRINSICS
    rot = object_T_sensor[:3, :3].astype(np.float32)
    xs, ys = (
        (uf + np.float32(c0 - k.cx)) * (z / np.float32(k.fx)),
        (vf + np.float32(r0 - k.cy)) * (z / np.float32(k.fy)),
    )
    pts_o = np.empty((len(z), 3), np.float32)
    for i in range(3):
        pts_o[:, i] = (
            rot[i, 0] * xs + rot[i, 1] * ys + rot[i, 2] * z + np.float32(object_T_sensor[i, 3])
        )
    return pts_o


def texture_relief(
    textures: list[MicroTexture],
    generic: MicroTexture,
    pts_o: np.ndarray,
    normal_o: np.ndarray,
    lut_vu: np.ndarray,
) -> np.ndarray:
    """Micro-texture height at each point, by its label (index len(textures) = generic)."""
    present = np.nonzero(np.bincount(lut_vu, minlength=len(textures) + 1))[0]
    relief = np.empty(len(pts_o), np.float32)
    for idx in present:
        sel = slice(None) if len(present) == 1 else lut_vu == idx
        tex = textures[idx] if idx < len(textures) else generic
        relief[sel] = tex.height(pts_o[sel], normal_o)
    return relief


def indentation(
    d: np.ndarray,
    m: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    relief: np.ndarray,
    comp: np.ndarray,
    smooth_px: float,
    far: np.float32,
) -> np.ndarray:
    """Indentation of the gel: texture stands proud of the surface, soft surfaces reach further.

    `d` is the crop's object depth, `m` its near pixels (v, u), `comp` per-pixel compliance;
    with `smooth_px` > 0 the depth is smoothed first, missing depth counting as `far`.
    """
    z = d[v, u]
    pen = np.zeros(d.shape, np.float32)
    if smooth_px > 0:
        # Missing depth (beyond the far plane) counts as far away, never as contact.
        z = cv2.GaussianBlur(np.where(d > 0, d, far), (0, 0), smooth_px)[v, u]
    pen[v, u] = relief - z
    pen += GEL_DISTANCE_M + SOFT_REACH_M * comp
    pen[~m] = 0.0
    np.clip(pen, 0.0, MAX_PENETRATION_M, out=pen)
    return pen


def elastomer(pen: np.ndarray, comp: np.ndarray, blur_px: float, soft_blur_px: float) -> np.ndarray:
    """Elastomer smoothing of an indentation, stronger where the material is soft."""
    w = cv2.GaussianBlur(comp, (0, 0), soft_blur_px)
    h = cv2.GaussianBlur(pen, (0, 0), blur_px)
    h += w * (cv2.GaussianBlur(pen, (0, 0), soft_blur_px) - h)
    return h


def led_shading(
    h: np.ndarray, gloss: np.ndarray, light_gain: float, press_gain: float
) -> np.ndarray:
    """RGB change over the background of the gel pressed in by height `h` (grey levels).

    Normals of the pressed gel (height toward the camera) in the sensor frame:
    n = (-gx, -gy, -1) / |.|, written out per component (small arrays, many pixels).
    Central differences (one-sided at the crop border, where h is 0 anyway).
    """
    gx = cv2.Sobel(
        h, cv2.CV_32F, 1, 0, ksize=1, scale=0.5 / PIXEL_M, borderType=cv2.BORDER_REPLICATE
    )
    gy = cv2.Sobel(
        h, cv2.CV_32F, 0, 1, ksize=1, scale=0.5 / PIXEL_M, borderType=cv2.BORDER_REPLICATE
    )
    nz = -1.0 / np.sqrt(gx * gx + gy * gy + 1.0)
    nx, ny = gx * nz, gy * nz
    response = np.empty((*h.shape, 3), np.float32)
    for i, ((lx, ly, lz), (hx, hy, hz)) in enumerate(zip(_LIGHT_DIRS, _HALF_DIRS)):
        lambert = nx * lx + ny * ly + (nz + 1.0) * lz  # n.l minus its flat-gel value (-lz)
        cos_h = np.maximum(nx * hx + ny * hy + nz * hz, 0.0)
        response[..., i] = lambert + gloss * (_pow32(cos_h) - _pow32(-hz))
    shading = cv2.transform(response, light_gain * _LIGHT_RGB.T)  # lights -> RGB
    shading += ((press_gain / MAX_PENETRATION_M) * h)[..., None]
    return shading
