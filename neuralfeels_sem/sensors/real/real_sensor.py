"""sensor=real: DIGITs + RealSense + hand (Allegro or Dynamixel) combined into Frames.

`open()` tries every configured device and collects what is missing, then raises one
HardwareError with one line per missing device (run.py prints it and exits 2). During a
run a device that stops answering is dropped with one warning; the others go on, and the
run ends early only when no device is left. Frames are assembled at `fps` from the latest
reading of each stream; per-stream timestamps of the last frame are in `stream_times`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from hydra.utils import get_class

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS
from neuralfeels_sem.core.errors import ConfigError, HardwareError, UserError
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.sensors.base import Sensor, check_pace
from neuralfeels_sem.sensors.real.aruco_pose import MISSING_LAYOUT, ArucoObjectPose
from neuralfeels_sem.sensors.real.digit import DigitArray
from neuralfeels_sem.sensors.real.hand_kinematics import kinematics_target
from neuralfeels_sem.sensors.real.poses import pose_from_vector
from neuralfeels_sem.sensors.real.realsense import RealSenseCamera

log = logging.getLogger(__name__)


def _label(device: Any) -> str:
    return getattr(device, "label", None) or getattr(device, "name", type(device).__name__)


class RealSensor(Sensor):
    needs_object = False  # tasks may skip building the object for this sensor

    def __init__(
        self,
        digit: DigitArray | None = None,
        camera: RealSenseCamera | None = None,
        hand: Any = None,
        object_pose: ArucoObjectPose | None = None,
        duration_s: float = 30.0,
        fps: float = 10.0,
        world_T_palm: Sequence[float] = (0.0,) * 6,
        world_T_object: Sequence[float] = (0.0,) * 6,
        name: str = "real",
        obj: Any = None,
        class_names: Sequence[str] | None = None,
        pace: str = "realtime",
    ) -> None:
        if fps <= 0 or duration_s <= 0:
            raise ValueError(f"fps={fps} and duration_s={duration_s} must be > 0")
        if object_pose is not None and camera is None:
            raise ConfigError(
                "sensor.object_pose (ArUco markers) needs sensor.camera: configure the camera or set sensor.object_pose=null"
            )
        self.digits = [] if digit is None else list(digit.cameras)
        self.camera = camera
        self.hand = hand
        self.object_pose = object_pose  # None: the pose stays world_T_object
        self.duration_s = duration_s
        self.frame_period_s = 1.0 / fps
        self.world_T_palm = pose_from_vector(world_T_palm)
        self.world_T_object = pose_from_vector(world_T_object)
        # The hand names its model (sensor.hand.kinematics): each DIGIT pose is FK of the hand.
        self.kinematics_name = getattr(hand, "kinematics", "allegro")
        self.name = name
        self.obj = obj  # unused on hardware; accepted so every sensor is completed alike
        self.class_names = None if class_names is None else list(class_names)
        # realtime (default): the mapper keeps up with the devices by taking the newest frame.
        self.pace = check_pace(pace)
        self.stream_times: dict[str, float] = {}
        self._kinematics = None
        self._opened: list[Any] = []
        self._dead: set[int] = set()

    def __len__(self) -> int:
        return int(round(self.duration_s / self.frame_period_s))

    def _devices(self) -> list[Any]:
        return [
            *self.digits,
            *([self.camera] if self.camera else []),
            *([self.hand] if self.hand else []),
        ]

    @property
    def calibration(self) -> dict:
        """What a recording needs to interpret the streams later."""
        info: dict = {"world_T_palm": self.world_T_palm.tolist()}
        if self.camera is not None and self.camera.intrinsics is not None:
            info["camera"] = {
                "name": self.camera.name,
                "intrinsics": self.camera.intrinsics.to_dict(),
                "world_T_camera": self.camera.world_T_camera.tolist(),
                "depth_scale": self.camera.depth_scale,
            }
        info["digit_intrinsics"] = DIGIT_INTRINSICS.to_dict()
        return info

    def open(self) -> None:
        if not self._devices():
            raise HardwareError(
                "sensor=real has no device configured: set sensor.digit, sensor.camera or sensor.hand"
            )
        errors: list[str] = []
        if self.object_pose is not None and not self.object_pose.object_T_marker:
            errors.append(MISSING_LAYOUT)
        if self.hand is not None:
            try:
                target = kinematics_target(self.kinematics_name)
                self._kinematics = get_class(target)(world_T_palm=self.world_T_palm)
                self.hand.set_joint_limits(np.asarray(self._kinematics.joint_limits))
            except Exception as exc:  # import or construction of the model failed
                errors.append(
                    f"hand kinematics {self.kinematics_name!r} unavailable ({type(exc).__name__}: {exc}): set sensor.hand.kinematics"
                )
        for device in self._devices():
            try:
                device.open()
                self._opened.append(device)
            except UserError as exc:
                errors.append(str(exc))
        if errors:
            self.close()
            raise HardwareError("\n".join(errors))
        log.info("sensor=real: opened %s", ", ".join(_label(d) for d in self._devices()))

    def hand_model(self):
        """The configured hand kinematics (sensor.hand.kinematics), built by open(); None
        without a hand. A model without link meshes (LEAP) lets camera segmentation skip
        the hand step."""
        return self._kinematics

    def close(self) -> None:
        while self._opened:
            device = self._opened.pop()
            try:
                device.close()
            except Exception as exc:  # closing a broken device must not hide the run's results
                log.warning("closing %s failed: %s", _label(device), exc)

    def _read(self, device: Any, read) -> Any:
        """Call `read`; on failure drop the device with one warning and return None."""
        if id(device) in self._dead:
            return None
        try:
            return read()
        except Exception as exc:  # any failure of one device must not end the others' run
            self._dead.add(id(device))
            log.warning(
                "%s stopped answering (%s); the run goes on without it", _label(device), exc
            )
            return None

    def _read_tactile(
        self, poses: dict, stamps: dict[str, float], start: float
    ) -> dict[str, TactileReading]:
        """One reading per DIGIT that answered, posed by `poses` (identity if unknown); stamps each."""
        tactile = {}
        for cam in self.digits:
            image = self._read(cam, cam.read)
            if image is None:
                continue
            stamps[f"digit/{cam.finger}"] = time.monotonic() - start
            tactile[cam.finger] = TactileReading(
                finger=cam.finger,
                image=image,
                world_T_sensor=np.asarray(poses.get(cam.finger, np.eye(4)), dtype=np.float64),
                intrinsics=DIGIT_INTRINSICS,
                background=cam.background,
            )
        return tactile

    def _read_camera(
        self, stamps: dict[str, float], start: float, world_T_object: np.ndarray
    ) -> tuple[CameraReading | None, np.ndarray]:
        """The camera's reading (None if absent or silent) and the object pose, updated from its markers."""
        if self.camera is None:
            return None, world_T_object
        rgbd = self._read(self.camera, self.camera.read)
        if rgbd is None:
            return None, world_T_object
        stamps["camera"] = time.monotonic() - start
        camera_reading = CameraReading(
            rgb=rgbd[0],
            depth=rgbd[1],
            intrinsics=self.camera.intrinsics,
            world_T_camera=self.camera.world_T_camera,
            name=self.camera.name,
        )
        if self.object_pose is not None:
            estimate = self.object_pose.estimate(
                rgbd[0], self.camera.intrinsics, self.camera.world_T_camera
            )
            if estimate is not None:
                world_T_object = estimate
        return camera_reading, world_T_object

    def frames(self) -> Iterator[Frame]:
        start = time.monotonic()
        last_q: np.ndarray | None = None
        world_T_object = self.world_T_object.copy()
        for index in range(len(self)):
            delay = start + index * self.frame_period_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if all(id(d) in self._dead for d in self._devices()):
                log.warning(
                    "sensor=real: every device stopped answering; ending after %d frames", index
                )
                return
            stamps: dict[str, float] = {}
            q = None
            if self.hand is not None:
                q = self._read(self.hand, self.hand.read_joints)
                if q is not None:
                    stamps["hand"] = time.monotonic() - start
                    last_q = q
            poses = (
                self._kinematics.sensor_poses(last_q)
                if last_q is not None and self._kinematics
                else {}
            )
            tactile = self._read_tactile(poses, stamps, start)
            camera_reading, world_T_object = self._read_camera(stamps, start, world_T_object)
            self.stream_times = stamps
            yield Frame(
                index=index,
                time_s=time.monotonic() - start,
                world_T_object=world_T_object.copy(),
                tactile=tactile,
                camera=camera_reading,
                joint_positions=q,
            )
