"""task=calibrate: camera-to-hand extrinsics from rendered views of an ArUco board."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.geometry import Intrinsics, look_at
from neuralfeels_sem.sensors.real.poses import pose_from_vector
from neuralfeels_sem.tasks import calibrate
from tests.helpers import compose_config
from tests.sensors.real.synthetic_views import board_texture, render_plane

INTR = Intrinsics(fx=610.0, fy=610.0, cx=319.5, cy=239.5, width=640, height=480)
PALM_T_BOARD = [
    0.02,
    -0.01,
    0.05,
    3.0,
    0.4,
    0.0,
]  # about 180 deg about x: the printed face looks up
WORLD_T_PALM = [0.0, 0.0, 0.2, 0.1, 0.0, 0.0]


def board_view(world_T_camera: np.ndarray) -> np.ndarray:
    board = calibrate.make_board("DICT_4X4_50", 4, 3, 0.03, 0.006)
    texture, to_plane = board_texture(board, (1460, 1100))
    world_T_board = pose_from_vector(WORLD_T_PALM) @ pose_from_vector(PALM_T_BOARD)
    image = np.full((INTR.height, INTR.width, 3), 120, np.uint8)
    render_plane(image, texture, to_plane, np.linalg.inv(world_T_camera) @ world_T_board, INTR)
    return image


def camera_pose() -> np.ndarray:
    return look_at(np.array([0.25, -0.2, 0.55]), np.array([0.05, 0.03, 0.25]))


def test_calibration_recovers_the_camera_pose() -> None:
    world_T_camera = camera_pose()
    board = calibrate.make_board("DICT_4X4_50", 4, 3, 0.03, 0.006)
    result = calibrate.calibrate_camera_to_hand(
        [board_view(world_T_camera)] * 2,
        INTR,
        board,
        pose_from_vector(PALM_T_BOARD),
        pose_from_vector(WORLD_T_PALM),
    )
    assert result["images_used"] == 2 and result["markers_used"] == 24
    assert result["reprojection_rms_px"] < 0.5
    assert np.linalg.norm(result["world_T_camera"][:3, 3] - world_T_camera[:3, 3]) < 2e-3
    cos = (np.trace(result["world_T_camera"][:3, :3].T @ world_T_camera[:3, :3]) - 1) / 2
    assert np.rad2deg(np.arccos(np.clip(cos, -1, 1))) < 0.5


def test_task_writes_yaml_that_the_camera_reads(tmp_path, monkeypatch) -> None:
    images = tmp_path / "images"
    images.mkdir()
    cv2.imwrite(str(images / "0.png"), cv2.cvtColor(board_view(camera_pose()), cv2.COLOR_RGB2BGR))
    monkeypatch.chdir(tmp_path)
    cfg = compose_config(
        [
            "task=calibrate",
            f"task.images={images}",
            f"task.intrinsics=[{INTR.fx},{INTR.fy},{INTR.cx},{INTR.cy}]",
            f"task.palm_T_board={PALM_T_BOARD}".replace(" ", ""),
            f"task.world_T_palm={WORLD_T_PALM}".replace(" ", ""),
        ]
    )
    summary = calibrate.run(cfg)
    data = yaml.safe_load((tmp_path / "camera_calibration.yaml").read_text())
    assert summary["images_used"] == 1 and data["intrinsics"]["fx"] == INTR.fx
    from neuralfeels_sem.sensors.real.realsense import RealSenseCamera

    loaded = RealSenseCamera(
        calibration_file=str(tmp_path / "camera_calibration.yaml")
    )._extrinsics()
    assert np.linalg.norm(loaded[:3, 3] - camera_pose()[:3, 3]) < 2e-3


def test_no_board_in_view_is_a_data_error() -> None:
    board = calibrate.make_board("DICT_4X4_50", 4, 3, 0.03, 0.006)
    blank = np.full((480, 640, 3), 120, np.uint8)
    with pytest.raises(DataError, match="task.board"):
        calibrate.calibrate_camera_to_hand([blank], INTR, board, np.eye(4), np.eye(4))
