"""Render planar textures (ArUco markers, boards) into a pinhole camera image with a known pose."""

from __future__ import annotations

import cv2
import numpy as np

from neuralfeels_sem.core.geometry import Intrinsics


def render_plane(
    canvas: np.ndarray,
    texture: np.ndarray,
    texture_to_plane: np.ndarray,
    camera_T_plane: np.ndarray,
    intrinsics: Intrinsics,
    supersample: int = 4,
) -> None:
    """Draw a grey texture lying on the plane z=0 of `camera_T_plane` into `canvas` (RGB, in place).

    `texture_to_plane` (3x3) maps texture pixel (u, v, 1) to plane metres (x, y, 1). The view
    is rendered `supersample` times larger and area-averaged down, like a real lens and sensor
    (a direct warp of a large texture aliases and breaks marker bits).
    """
    s = supersample
    # Pixel centres: big pixel (s u + (s - 1) / 2) covers small pixel u.
    big_from_small = np.array([[s, 0, (s - 1) / 2.0], [0, s, (s - 1) / 2.0], [0, 0, 1.0]])
    plane_to_image = big_from_small @ intrinsics.matrix @ camera_T_plane[:3][:, [0, 1, 3]]
    homography = plane_to_image @ texture_to_plane
    size = (intrinsics.width * s, intrinsics.height * s)
    warped = cv2.warpPerspective(texture, homography, size, flags=cv2.INTER_LINEAR)
    coverage = cv2.warpPerspective(
        np.full(texture.shape, 255, np.uint8), homography, size, flags=cv2.INTER_LINEAR
    )
    small = (intrinsics.width, intrinsics.height)
    warped = cv2.resize(warped, small, interpolation=cv2.INTER_AREA)
    coverage = cv2.resize(coverage, small, interpolation=cv2.INTER_AREA)
    inside = coverage > 127
    canvas[inside] = warped[inside][:, None]


def marker_texture(
    dictionary: cv2.aruco.Dictionary, marker_id: int, length_m: float, side_px: int = 200
) -> tuple[np.ndarray, np.ndarray]:
    """A marker with a white quiet zone, and its pixel -> marker-frame (x right, y up) map."""
    pad = side_px // 4
    marker = cv2.aruco.generateImageMarker(dictionary, marker_id, side_px)
    texture = np.full((side_px + 2 * pad, side_px + 2 * pad), 255, np.uint8)
    texture[pad : pad + side_px, pad : pad + side_px] = marker
    s = length_m / side_px
    c = pad + side_px / 2.0 - 0.5
    return texture, np.array([[s, 0, -s * c], [0, -s, s * c], [0, 0, 1.0]])


def board_texture(
    board: cv2.aruco.GridBoard, size_px: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """A board image and its pixel -> board-frame map, fitted from the markers' known corners."""
    texture = board.generateImage(size_px, marginSize=40)
    detector = cv2.aruco.ArucoDetector(board.getDictionary(), cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(texture)
    obj = np.asarray(board.getObjPoints())
    board_ids = list(np.asarray(board.getIds()).ravel())
    pixels = np.concatenate([c.reshape(4, 2) for c in corners])
    plane = np.concatenate([obj[board_ids.index(int(i)), :, :2] for i in ids.ravel()])
    design = np.hstack([pixels, np.ones((len(pixels), 1))])
    affine, *_ = np.linalg.lstsq(design, plane, rcond=None)
    return texture, np.vstack([affine.T, [0, 0, 1.0]])
