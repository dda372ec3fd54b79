"""NeuralFeels' FeelSight log layout: reader (-> Frames) and exporter (Frames -> layout).

    <log>/allegro/<finger>/image/<i>.jpg     DIGIT images (BGR jpg), i = 0..N-1
    <log>/allegro/<finger>/mask/<i>.jpg      sim only: contact mask (0 / 255)
    <log>/realsense/<cam>/image/<i>.jpg      camera colour
    <log>/realsense/<cam>/seg/<i>.jpg        sim only: segmentation, 255 = object
    <log>/realsense/<cam>/depth.npz          "depth" (N, H, W) and "depth_scale"
    <log>/data.pkl                           time, digit_info, allegro {base_pose, joint_state},
                                             object {pose}, realsense {<cam>: {intrinsics, pose}}

NeuralFeels uses OpenGL-style cameras (looking along -z, depth stored negative in its sim
logs); this module converts at this boundary: depth is read as |depth| * depth_scale and
camera poses as `pose @ OPENGL_T_OPENCV`. DIGIT poses are not in FeelSight logs
(NeuralFeels computes them from joint_state with its Allegro URDF); our exporter adds
them under the extra key `semanticfeels` (OpenCV convention) and the reader uses them
when present, otherwise the hand model `kinematics` (our hand, not NeuralFeels' URDF).
FeelSight logs carry no no-contact background: the first image of each finger stands in.
data.pkl is a pickle: only read logs from sources you trust.
"""

from __future__ import annotations

import pickle
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.core.geometry import OPENGL_T_OPENCV, Intrinsics
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sensors.replay.damage import READ_ERRORS, DamagedFrame, read_or_damaged

JPEG_QUALITY = 95


def _intrinsics_to_feelsight(intrinsics: Intrinsics) -> dict:
    return {
        "w": intrinsics.width,
        "h": intrinsics.height,
        "fx": intrinsics.fx,
        "fy": intrinsics.fy,
        "cx": intrinsics.cx,
        "cy": intrinsics.cy,
    }


def _intrinsics_from_feelsight(d: dict) -> Intrinsics:
    return Intrinsics(
        fx=float(d["fx"]),
        fy=float(d["fy"]),
        cx=float(d["cx"]),
        cy=float(d["cy"]),
        width=int(d["w"]),
        height=int(d["h"]),
    )


def _write_jpg(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])


@dataclass
class _Tracks:
    """Per-frame values export_feelsight gathers for data.pkl and depth.npz."""

    times: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    object_poses: list = field(default_factory=list)
    gt_object_poses: list = field(default_factory=list)
    digit_poses: dict[str, list] = field(default_factory=lambda: {f: [] for f in FINGERS})
    depths: list = field(default_factory=list)
    camera_poses: list = field(default_factory=list)
    camera_name: str | None = None
    camera_intrinsics: Intrinsics | None = None

    def add_state(self, frame: Frame) -> None:
        """The frame's time, joint angles (NaN when absent) and object poses."""
        self.times.append(frame.time_s)
        self.joints.append(
            np.full(16, np.nan)
            if frame.joint_positions is None
            else np.asarray(frame.joint_positions, np.float64)
        )
        self.object_poses.append(frame.world_T_object)
        self.gt_object_poses.append(
            frame.world_T_object if frame.gt_world_T_object is None else frame.gt_world_T_object
        )

    def data(self) -> dict:
        """data.pkl's contents, with our DIGIT poses and ground-truth object poses added."""
        fingers = [f for f in FINGERS if any(p is not None for p in self.digit_poses[f])]
        return {
            "time": np.asarray(self.times),
            "digit_info": {
                "intrinsics": _intrinsics_to_feelsight(DIGIT_INTRINSICS),
                "cam_dist": GEL_DISTANCE_M,
                "depth_scale": 1.0,
            },
            "allegro": {"base_pose": np.eye(4), "joint_state": np.stack(self.joints)},
            "object": {"pose": list(np.stack(self.object_poses))},
            "realsense": {
                self.camera_name: {
                    "intrinsics": _intrinsics_to_feelsight(self.camera_intrinsics),
                    "pose": np.stack(self.camera_poses),
                }
            },
            "semanticfeels": {
                "digit_poses": {
                    f: np.stack([p if p is not None else np.eye(4) for p in self.digit_poses[f]])
                    for f in fingers
                },
                "gt_object_pose": np.stack(self.gt_object_poses),
            },
        }


def _export_digits(out: Path, i: int, frame: Frame, tracks: _Tracks) -> None:
    """Write each finger's DIGIT image (and sim contact mask); note its pose, None if absent."""
    for finger in FINGERS:
        reading = frame.tactile.get(finger)
        tracks.digit_poses[finger].append(None if reading is None else reading.world_T_sensor)
        if reading is None:
            continue
        _write_jpg(out / "allegro" / finger / "image" / f"{i}.jpg", reading.image)
        if reading.gt_contact_mask is not None:
            _write_jpg(
                out / "allegro" / finger / "mask" / f"{i}.jpg",
                reading.gt_contact_mask.astype(np.uint8) * 255,
            )


def _export_camera(out: Path, i: int, frame: Frame, tracks: _Tracks) -> None:
    """Write the camera's colour (and sim segmentation); note its depth and OpenGL pose."""
    cam = frame.camera
    if cam is None:
        raise DataError(
            f"frame {frame.index} has no camera image: FeelSight logs need one every frame"
        )
    # FeelSight names: front-left
    tracks.camera_name = tracks.camera_name or cam.name.replace("_", "-")
    tracks.camera_intrinsics = tracks.camera_intrinsics or cam.intrinsics
    folder = out / "realsense" / tracks.camera_name
    _write_jpg(folder / "image" / f"{i}.jpg", cam.rgb)
    if cam.mask is not None:
        _write_jpg(folder / "seg" / f"{i}.jpg", cam.mask.astype(np.uint8) * 255)
    tracks.depths.append(-cam.depth.astype(np.float32))  # NeuralFeels' sim logs store -z (OpenGL)
    tracks.camera_poses.append(cam.world_T_camera @ np.linalg.inv(OPENGL_T_OPENCV))


def export_feelsight(frames: Iterable[Frame], out_dir: str | Path, total: int | None = None) -> int:
    """Write Frames in the FeelSight layout; returns the number of frames written."""
    out = Path(out_dir)
    if (out / "data.pkl").exists():
        raise DataError(f"{out} already holds a FeelSight log: choose another directory")
    tracks = _Tracks()
    count = 0
    for i, frame in enumerate(tqdm(frames, total=total, desc="export FeelSight", unit="frame")):
        tracks.add_state(frame)
        _export_digits(out, i, frame, tracks)
        _export_camera(out, i, frame, tracks)
        count += 1
    if count == 0:
        raise DataError("no frames to export")
    np.savez_compressed(
        out / "realsense" / tracks.camera_name / "depth.npz",
        depth=np.stack(tracks.depths),
        depth_scale=np.float32(1.0),
    )
    data = tracks.data()
    with open(out / "data.pkl", "wb") as f:
        pickle.dump(data, f)
    return count


def _read_data(pkl: Path) -> dict:
    """data.pkl; DataError in one line when it is truncated or not a FeelSight dict."""
    try:
        with open(pkl, "rb") as f:
            data = pickle.load(f)
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, IndexError) as exc:
        raise DataError(
            f"FeelSight log {pkl} is damaged ({type(exc).__name__}); restore it from the source"
        ) from exc
    if not isinstance(data, dict):
        raise DataError(f"FeelSight log {pkl} holds no dict: not a FeelSight log")
    return data


def _read_depth(path: Path) -> tuple[np.ndarray, float]:
    """depth.npz's depth stack and scale; DataError in one line when missing or damaged."""
    try:
        with np.load(path) as depth:
            return depth["depth"], float(depth["depth_scale"])
    except READ_ERRORS as exc:
        raise DataError(
            f"FeelSight log depth {path} is missing or damaged ({type(exc).__name__}); "
            "restore it (every frame's depth is in this one file)"
        ) from exc


class FeelSightReader:
    """Frames from one FeelSight log directory (one camera)."""

    def __init__(
        self,
        path: str | Path,
        camera: str = "front-left",
        kinematics: str = "neuralfeels_sem.sim.kinematics.HandKinematics",
    ) -> None:
        self.path = Path(path)
        pkl = self.path / "data.pkl"
        if not pkl.is_file():
            raise DataError(
                f"{self.path} is not a FeelSight log (no data.pkl): fix sensor.recording"
            )
        self.data = _read_data(pkl)
        cams = self.data.get("realsense", {})
        camera = camera.replace("_", "-")  # FeelSight spells cameras front-left; we say front_left
        if camera not in cams:
            raise DataError(
                f"FeelSight log {self.path} has no camera {camera!r} (has {sorted(cams)}): set sensor.camera"
            )
        self.camera = camera
        self.camera_intrinsics = _intrinsics_from_feelsight(cams[camera]["intrinsics"])
        poses = np.asarray(cams[camera]["pose"], dtype=np.float64)
        self.camera_poses = poses[None] if poses.ndim == 2 else poses
        self.depth, self.depth_scale = _read_depth(self.path / "realsense" / camera / "depth.npz")
        self.times = np.asarray(self.data["time"], dtype=np.float64)
        self.object_poses = np.asarray(self.data["object"]["pose"], dtype=np.float64)
        self.joint_states = np.asarray(self.data["allegro"]["joint_state"], dtype=np.float64)
        self.fingers = [f for f in FINGERS if (self.path / "allegro" / f / "image").is_dir()]
        self.tactile_intrinsics = _intrinsics_from_feelsight(self.data["digit_info"]["intrinsics"])
        extra = self.data.get("semanticfeels", {})
        self.digit_poses = extra.get("digit_poses")
        self.gt_object_poses = extra.get("gt_object_pose")
        self._kinematics_target = kinematics
        self._kinematics = None
        self._backgrounds: dict[str, np.ndarray] = {}
        self._length = min(len(self.times), len(self.depth), len(self.object_poses))
        self.tail_dropped = 0  # data.pkl and depth.npz are written once, at the end

    class_names = None  # FeelSight has no material labels

    def __len__(self) -> int:
        return self._length

    @property
    def frame_period_s(self) -> float:
        return float(np.median(np.diff(self.times))) if len(self.times) > 1 else 0.1

    def _image(self, path: Path, index: int) -> np.ndarray:
        """An RGB image of frame `index`; DamagedFrame when missing or unreadable."""
        image = read_or_damaged(index, path, self.path, lambda p: cv2.imread(str(p)))
        return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)

    def _first_image(self, finger: str) -> np.ndarray:
        """Frame 0's image stands in for the no-contact background; a log without it
        cannot be replayed (every frame needs a background)."""
        try:
            return self._image(self.path / "allegro" / finger / "image" / "0.jpg", 0)
        except DamagedFrame as damage:
            raise DataError(
                f"FeelSight log {self.path}: {damage.file} {damage.why}, and it is the "
                f"{finger} finger's background; restore it"
            ) from damage

    def hand_model(self) -> object:
        """The log's Allegro model at its base pose (for DIGIT poses and segmentation)."""
        if self._kinematics is None:
            from hydra.utils import get_class

            try:
                base = np.asarray(self.data["allegro"]["base_pose"], dtype=np.float64)
                self._kinematics = get_class(self._kinematics_target)(world_T_palm=base)
            except Exception as exc:  # the hand model is another module; say what is missing
                raise DataError(
                    f"FeelSight log {self.path} needs the hand model {self._kinematics_target} ({exc})"
                ) from exc
        return self._kinematics

    def _sensor_poses(self, i: int) -> dict[str, np.ndarray]:
        if self.digit_poses is not None:
            return {
                f: np.asarray(self.digit_poses[f][i], dtype=np.float64) for f in self.digit_poses
            }
        return self.hand_model().sensor_poses(self.joint_states[i])

    def frame(self, i: int) -> Frame:
        poses = self._sensor_poses(i)
        tactile = {}
        for finger in self.fingers:
            image = self._image(self.path / "allegro" / finger / "image" / f"{i}.jpg", i)
            if finger not in self._backgrounds:
                self._backgrounds[finger] = self._first_image(finger)
            mask_path = self.path / "allegro" / finger / "mask" / f"{i}.jpg"
            mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE) if mask_path.is_file() else None
            tactile[finger] = TactileReading(
                finger=finger,
                image=image,
                world_T_sensor=poses[finger],
                intrinsics=self.tactile_intrinsics,
                background=self._backgrounds[finger],
                gt_contact_mask=None if mask is None else mask > 127,
            )
        folder = self.path / "realsense" / self.camera
        seg_path = folder / "seg" / f"{i}.jpg"
        seg = cv2.imread(str(seg_path), cv2.IMREAD_GRAYSCALE) if seg_path.is_file() else None
        camera = CameraReading(
            rgb=self._image(folder / "image" / f"{i}.jpg", i),
            depth=(np.abs(self.depth[i]) * self.depth_scale).astype(np.float32),
            intrinsics=self.camera_intrinsics,
            world_T_camera=self.camera_poses[min(i, len(self.camera_poses) - 1)] @ OPENGL_T_OPENCV,
            mask=None
            if seg is None
            else seg > 191,  # 255 = object (127 marks the hand in NeuralFeels' sim)
            name=self.camera.replace("-", "_"),
        )
        joints = self.joint_states[i] if i < len(self.joint_states) else None
        gt = (
            None
            if self.gt_object_poses is None
            else np.asarray(self.gt_object_poses[i], dtype=np.float64)
        )
        return Frame(
            index=i,
            time_s=float(self.times[i]),
            world_T_object=self.object_poses[i],
            tactile=tactile,
            camera=camera,
            gt_world_T_object=gt,
            joint_positions=None if joints is None or np.isnan(joints).any() else joints,
        )
