"""Intel RealSense D435 / D435i through pyrealsense2: colour + depth aligned to colour.

Intrinsics come from the device (colour stream, after alignment the depth shares them);
the camera's pose in the world comes from calibration (task=calibrate writes a YAML with
`world_T_camera`) or from `world_T_camera` in the config.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from neuralfeels_sem.core.errors import ConfigError, DataError, HardwareError
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.sensors.real.poses import pose_from_vector

log = logging.getLogger(__name__)


def intrinsics_from_rs(rs_intrinsics) -> Intrinsics:
    """pyrealsense2.intrinsics (fx, fy, ppx, ppy, width, height) -> our Intrinsics."""
    return Intrinsics(
        fx=float(rs_intrinsics.fx),
        fy=float(rs_intrinsics.fy),
        cx=float(rs_intrinsics.ppx),
        cy=float(rs_intrinsics.ppy),
        width=int(rs_intrinsics.width),
        height=int(rs_intrinsics.height),
    )


def depth_to_metres(depth_raw: np.ndarray, depth_scale: float) -> np.ndarray:
    """uint16 depth units -> float32 metres (0 stays 0 = invalid)."""
    if depth_raw.dtype != np.uint16:
        raise ValueError(f"RealSense depth must be uint16, got {depth_raw.dtype}")
    return depth_raw.astype(np.float32) * np.float32(depth_scale)


def load_world_T_camera(path: str | Path) -> np.ndarray:
    """`world_T_camera` (4x4 rows) from a calibration YAML written by task=calibrate."""
    path = Path(path)
    if not path.is_file():
        raise DataError(
            f"calibration file {path} not found: run `python run.py task=calibrate` or fix the path"
        )
    data = yaml.safe_load(path.read_text()) or {}
    if "world_T_camera" not in data:
        raise DataError(f"calibration file {path} has no world_T_camera: re-run task=calibrate")
    pose = np.asarray(data["world_T_camera"], dtype=np.float64)
    if pose.shape != (4, 4):
        raise DataError(f"calibration file {path}: world_T_camera must be 4x4, got {pose.shape}")
    return pose


class RealSenseCamera:
    """One RealSense; `serial=None` takes the first one connected."""

    def __init__(
        self,
        serial: str | None = None,
        name: str = "front_left",
        width: int = 640,
        height: int = 480,
        fps: int = 30,
        world_T_camera: Sequence[float] | None = None,
        calibration_file: str | None = None,
        warmup_frames: int = 15,
        timeout_ms: int = 1000,
    ) -> None:
        self.serial = serial
        self.name = name
        self.width, self.height, self.fps = width, height, fps
        self.world_T_camera_config = world_T_camera
        self.calibration_file = calibration_file
        self.warmup_frames = warmup_frames
        self.timeout_ms = timeout_ms
        self.intrinsics: Intrinsics | None = None
        self.depth_scale = 0.001
        self.world_T_camera = np.eye(4)
        self._pipeline = None
        self._align = None

    @property
    def label(self) -> str:
        return f"RealSense {self.name} (serial {self.serial or 'any'})"

    def _extrinsics(self) -> np.ndarray:
        if self.calibration_file:
            return load_world_T_camera(self.calibration_file)
        if self.world_T_camera_config is not None:
            return pose_from_vector(self.world_T_camera_config)
        raise ConfigError(
            f"{self.label} has no extrinsics: run task=calibrate and set sensor.camera.calibration_file, "
            "or set sensor.camera.world_T_camera"
        )

    def open(self) -> None:
        try:
            import pyrealsense2 as rs
        except ImportError:
            raise HardwareError(
                f"{self.label}: pyrealsense2 is not installed (PyPI has it for x86-64 Linux and "
                "Windows only): build librealsense with BUILD_PYTHON_BINDINGS=ON into this "
                "environment, or set sensor.camera=null"
            ) from None

        found = [d.get_info(rs.camera_info.serial_number) for d in rs.context().query_devices()]
        if not found:
            raise HardwareError(
                f"{self.label} not found (no RealSense connected): plug it into a USB3 port or set sensor.camera=null"
            )
        if self.serial and self.serial not in found:
            raise HardwareError(
                f"{self.label} not found (connected: {', '.join(found)}): set sensor.camera.serial"
            )
        self.world_T_camera = self._extrinsics()
        config = rs.config()
        if self.serial:
            config.enable_device(self.serial)
        config.enable_stream(rs.stream.depth, self.width, self.height, rs.format.z16, self.fps)
        config.enable_stream(rs.stream.color, self.width, self.height, rs.format.rgb8, self.fps)
        pipeline = rs.pipeline()
        try:
            profile = pipeline.start(config)
        except RuntimeError as exc:
            raise HardwareError(
                f"{self.label}: cannot start {self.width}x{self.height}@{self.fps} ({exc})"
            ) from exc
        self._pipeline = pipeline
        self.depth_scale = float(profile.get_device().first_depth_sensor().get_depth_scale())
        color_profile = profile.get_stream(rs.stream.color).as_video_stream_profile()
        self.intrinsics = intrinsics_from_rs(color_profile.get_intrinsics())
        self._align = rs.align(rs.stream.color)
        for _ in range(self.warmup_frames):  # auto-exposure settles
            self._pipeline.wait_for_frames(self.timeout_ms)

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """(rgb uint8 (H, W, 3), depth float32 metres (H, W)) aligned to colour."""
        if self._pipeline is None:
            raise RuntimeError(f"{self.label} is not open")
        try:
            frames = self._align.process(self._pipeline.wait_for_frames(self.timeout_ms))
        except RuntimeError as exc:
            raise HardwareError(f"{self.label}: no frame within {self.timeout_ms} ms") from exc
        depth = np.asanyarray(frames.get_depth_frame().get_data())
        rgb = np.asanyarray(frames.get_color_frame().get_data())
        return rgb.copy(), depth_to_metres(depth, self.depth_scale)

    def close(self) -> None:
        if self._pipeline is not None:
            try:
                self._pipeline.stop()
            finally:
                self._pipeline = None
