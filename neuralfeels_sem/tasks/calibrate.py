"""task=calibrate: camera-to-hand extrinsics from an ArUco board fixed to the hand, saved to YAML.

The board sits at a known pose on the palm (`task.palm_T_board`); the camera sees it, PnP
gives `camera_T_board`, so `palm_T_camera = palm_T_board @ inv(camera_T_board)` and
`world_T_camera = world_T_palm @ palm_T_camera`. Corners from every image are pooled in
one solve (camera and hand stay still while capturing). Images come from a folder
(`task.images=DIR`, with `task.intrinsics=[fx, fy, cx, cy]`) or live from `sensor.camera`.

    python run.py task=calibrate sensor=real                       # live RealSense
    python run.py task=calibrate task.images=DIR task.intrinsics=[615,615,320,240]
"""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
import yaml
from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.geometry import Intrinsics, invert_pose
from neuralfeels_sem.sensors.real.aruco_pose import aruco_dictionary, detect_markers, solve_pnp
from neuralfeels_sem.sensors.real.poses import pose_from_vector
from neuralfeels_sem.tasks.runner import output_dir

log = logging.getLogger(__name__)


def make_board(
    dictionary: str,
    markers_x: int,
    markers_y: int,
    marker_length_m: float,
    marker_separation_m: float,
) -> cv2.aruco.GridBoard:
    return cv2.aruco.GridBoard(
        (markers_x, markers_y), marker_length_m, marker_separation_m, aruco_dictionary(dictionary)
    )


def calibrate_camera_to_hand(
    images: list[np.ndarray],
    intrinsics: Intrinsics,
    board: cv2.aruco.GridBoard,
    palm_T_board: np.ndarray,
    world_T_palm: np.ndarray,
    min_markers: int = 2,
) -> dict:
    """Pool board corners over RGB `images`, solve PnP, return poses and the fit quality."""
    board_ids = [int(i) for i in np.asarray(board.getIds()).ravel()]
    corners_3d = np.asarray(board.getObjPoints(), dtype=np.float64)
    object_points, image_points, used = [], [], 0
    for image in images:
        found = {
            i: c for i, c in detect_markers(image, board.getDictionary()).items() if i in board_ids
        }
        if len(found) < min_markers:
            continue
        used += 1
        for marker_id, pixels in found.items():
            object_points.append(corners_3d[board_ids.index(marker_id)])
            image_points.append(pixels)
    if not used:
        raise DataError(
            f"calibration: no image shows >= {min_markers} board markers: check task.board (dictionary, size) and the view"
        )
    camera_T_board, rms = solve_pnp(
        np.concatenate(object_points), np.concatenate(image_points), intrinsics
    )
    palm_T_camera = palm_T_board @ invert_pose(camera_T_board)
    return {
        "world_T_camera": world_T_palm @ palm_T_camera,
        "palm_T_camera": palm_T_camera,
        "camera_T_board": camera_T_board,
        "reprojection_rms_px": rms,
        "images_used": used,
        "markers_used": len(object_points),
    }


def save_calibration(path: Path, result: dict, intrinsics: Intrinsics) -> None:
    data = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in result.items()}
    data["intrinsics"] = intrinsics.to_dict()
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def _load_images(folder: str) -> list[np.ndarray]:
    paths = sorted(
        p for p in Path(folder).glob("*") if p.suffix.lower() in (".png", ".jpg", ".jpeg")
    )
    if not paths:
        raise DataError(f"calibration: no .png/.jpg images in {folder}: fix task.images")
    return [cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB) for p in paths]


def _capture_live(cfg: DictConfig) -> tuple[list[np.ndarray], Intrinsics]:
    camera_cfg = cfg.sensor.get("camera") if "camera" in cfg.sensor else None
    if camera_cfg is None:
        raise ConfigError(
            "task=calibrate without task.images needs a camera: use sensor=real (sensor.camera)"
        )
    camera = instantiate(
        camera_cfg, world_T_camera=[0.0] * 6, calibration_file=None
    )  # extrinsics are the output
    camera.open()
    try:
        images = [camera.read()[0] for _ in range(int(cfg.task.num_images))]
    finally:
        camera.close()
    return images, camera.intrinsics


def run(cfg: DictConfig) -> dict:
    task = cfg.task
    board = make_board(
        task.board.dictionary,
        task.board.markers_x,
        task.board.markers_y,
        task.board.marker_length_m,
        task.board.marker_separation_m,
    )
    if task.images:
        if task.intrinsics is None:
            raise ConfigError("task.images needs the camera's task.intrinsics=[fx, fy, cx, cy]")
        images = _load_images(task.images)
        fx, fy, cx, cy = (float(v) for v in task.intrinsics)
        h, w = images[0].shape[:2]
        intrinsics = Intrinsics(fx=fx, fy=fy, cx=cx, cy=cy, width=w, height=h)
    else:
        images, intrinsics = _capture_live(cfg)
    result = calibrate_camera_to_hand(
        images,
        intrinsics,
        board,
        pose_from_vector(task.palm_T_board),
        pose_from_vector(task.world_T_palm),
    )
    path = output_dir() / task.out
    save_calibration(path, result, intrinsics)
    log.info(
        "calibration from %d images, %d markers, reprojection RMS %.2f px -> %s (use sensor.camera.calibration_file=%s)",
        result["images_used"],
        result["markers_used"],
        result["reprojection_rms_px"],
        path,
        path,
    )
    return {
        "calibration_file": str(path),
        "reprojection_rms_px": result["reprojection_rms_px"],
        "images_used": result["images_used"],
    }
