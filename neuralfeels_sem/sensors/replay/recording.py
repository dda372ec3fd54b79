"""Recording directory: write Frames as they come, read them back bit-exactly.

Layout (schema version 1):

    <dir>/meta.json                 schema_version, class_names, frame_period_s, fingers,
                                    digit/camera intrinsics, calibration, config, num_frames,
                                    hand_model (class path + palm pose, or null)
    <dir>/frames.jsonl              one JSON line per frame: index, time_s, per-stream stamps,
                                    joint_positions, world_T_object, gt_world_T_object,
                                    per-finger world_T_sensor, world_T_camera, camera name
    <dir>/tactile/<finger>/<i>.png  RGB tactile image (lossless PNG)
    <dir>/tactile/<finger>/background.png
    <dir>/camera/rgb/<i>.png        RGB
    <dir>/camera/depth/<i>.npy      float32 metres (lossless, uncompressed: zlib saves ~15% on
                                    real depth at 60x the time, and recording must keep up)
    <dir>/camera/mask/<i>.png       object mask 0/255 (when present)
    <dir>/gt/tactile/<finger>/<i>.npz  sim ground truth: contact_mask, depth, material

Frames are appended one line at a time and meta.json is rewritten on every flush, so a
run that stops early still leaves a readable recording. Poses are JSON floats (exact for
float64). Images are PNG (lossless); depth is .npy float32, so a replay is identical.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.sensors.replay.damage import DamagedFrame, read_or_damaged
from neuralfeels_sem.sensors.replay.recording_files import (
    imread_gray,
    imread_rgb,
    load_npz,
    read_meta,
    read_records,
)

SCHEMA_VERSION = 1


def _name(index: int) -> str:
    return f"{index:06d}"


def _pose(value: np.ndarray | None) -> list | None:
    return None if value is None else np.asarray(value, dtype=np.float64).tolist()


def _write_png(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    # PNG level 1: lossless like any level, ~1.5x faster than the default for ~4% more disk.
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise DataError(f"cannot write {path}: check disk space and permissions")


def _savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    np.savez_compressed(path, **arrays)


def _read_png(path: Path, rgb: bool = True) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_COLOR if rgb else cv2.IMREAD_UNCHANGED)
    if image is None:
        raise DataError(f"recording file {path} is missing or unreadable")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB) if rgb else image


class RecordingWriter:
    """Append Frames to a recording directory (created; must not hold another recording)."""

    def __init__(
        self,
        path: str | Path,
        class_names: Sequence[str] | None = None,
        frame_period_s: float = 0.1,
        config: dict | None = None,
        calibration: dict | None = None,
        workers: int = 4,
        hand_model: dict | None = None,
    ) -> None:
        if workers < 0:
            raise ValueError(f"workers={workers} must be >= 0")
        self.path = Path(path)
        self.workers = workers
        self.meta = {
            "schema_version": SCHEMA_VERSION,
            "class_names": None if class_names is None else list(class_names),
            "frame_period_s": float(frame_period_s),
            "fingers": [],
            "digit_intrinsics": {},
            "camera": None,
            "calibration": calibration or {},
            "config": config or {},
            # sensors/hand_spec.py: the hand model's class and palm pose, for segmentation
            "hand_model": hand_model,
            "num_frames": 0,
            "has_gt_material": False,
        }
        self._lines = None
        self._backgrounds: set[str] = set()
        self._pool: ThreadPoolExecutor | None = None
        self._pending: deque[Future] = deque()

    def _save(self, function, path: Path, data) -> None:
        """Run a file write now (workers=0) or on the pool; at most 64 writes stay pending.

        Arrays are copied before queuing: a sensor may reuse its buffers for the next frame.
        """
        if self._pool is None:
            function(path, data)
            return
        if isinstance(data, np.ndarray):
            data = data.copy()
        elif isinstance(data, dict):
            data = {k: np.array(v, copy=True) for k, v in data.items()}
        self._pending.append(self._pool.submit(function, path, data))
        while len(self._pending) > 8 * 8:
            self._pending.popleft().result()  # re-raises a failed write

    def _drain(self) -> None:
        while self._pending:
            self._pending.popleft().result()

    def open(self) -> None:
        if (self.path / "frames.jsonl").exists():
            raise DataError(f"{self.path} already holds a recording: choose another task.out")
        self.path.mkdir(parents=True, exist_ok=True)
        self._lines = open(self.path / "frames.jsonl", "w")  # noqa: SIM115 - kept open for the run
        # PNG encoding releases the GIL: a few threads keep recording at the rig's frame rate.
        self._pool = (
            ThreadPoolExecutor(self.workers, thread_name_prefix="recording")
            if self.workers
            else None
        )
        self._write_meta()

    def _write_meta(self) -> None:
        (self.path / "meta.json").write_text(json.dumps(self.meta, indent=1))

    def _write_tactile(self, finger: str, reading: TactileReading, name: str) -> dict:
        """Save one DIGIT image (its background once, its ground truth if any); return its record."""
        folder = self.path / "tactile" / finger
        self._save(_write_png, folder / f"{name}.png", reading.image)
        if finger not in self.meta["fingers"]:
            self.meta["fingers"].append(finger)
            self.meta["digit_intrinsics"][finger] = reading.intrinsics.to_dict()
        if reading.background is not None and finger not in self._backgrounds:
            self._save(_write_png, folder / "background.png", reading.background)
            self._backgrounds.add(finger)
        gt = {
            key: value
            for key, value in (
                ("contact_mask", reading.gt_contact_mask),
                ("depth", reading.gt_depth),
                ("material", reading.gt_material),
            )
            if value is not None
        }
        if "material" in gt:
            self.meta["has_gt_material"] = True
        if gt:
            gt_path = self.path / "gt" / "tactile" / finger / f"{name}.npz"
            gt_path.parent.mkdir(parents=True, exist_ok=True)
            self._save(_savez, gt_path, gt)
        return {
            "world_T_sensor": _pose(reading.world_T_sensor),
            "gt": sorted(gt),
        }

    def _write_camera(self, cam: CameraReading, name: str) -> dict:
        """Save the camera's RGB, depth and mask (if any); return its record."""
        self._save(_write_png, self.path / "camera" / "rgb" / f"{name}.png", cam.rgb)
        depth_path = self.path / "camera" / "depth" / f"{name}.npy"
        depth_path.parent.mkdir(parents=True, exist_ok=True)
        self._save(np.save, depth_path, cam.depth.astype(np.float32))
        if cam.mask is not None:
            mask_path = self.path / "camera" / "mask" / f"{name}.png"
            self._save(_write_png, mask_path, cam.mask.astype(np.uint8) * 255)
        if self.meta["camera"] is None:
            self.meta["camera"] = {"name": cam.name, "intrinsics": cam.intrinsics.to_dict()}
        return {
            "world_T_camera": _pose(cam.world_T_camera),
            "name": cam.name,
            "mask": cam.mask is not None,
        }

    def write(self, frame: Frame, stamps: dict[str, float] | None = None) -> None:
        if self._lines is None:
            raise RuntimeError("RecordingWriter.open() first")
        name = _name(frame.index)
        record = {
            "index": frame.index,
            "time_s": frame.time_s,
            "stamps": stamps or {},
            "world_T_object": _pose(frame.world_T_object),
            "gt_world_T_object": _pose(frame.gt_world_T_object),
            "joint_positions": None
            if frame.joint_positions is None
            else np.asarray(frame.joint_positions, np.float64).tolist(),
            "tactile": {},
            "camera": None,
        }
        for finger, reading in frame.tactile.items():
            record["tactile"][finger] = self._write_tactile(finger, reading, name)
        if frame.camera is not None:
            record["camera"] = self._write_camera(frame.camera, name)
        self._lines.write(json.dumps(record) + "\n")
        self._lines.flush()
        self.meta["num_frames"] += 1
        if self.meta["num_frames"] == 1 or self.meta["num_frames"] % 50 == 0:
            self._write_meta()

    def close(self) -> None:
        """Finish pending writes, then close frames.jsonl and write meta.json."""
        try:
            self._drain()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)
                self._pool = None
            if self._lines is not None:
                self._lines.close()
                self._lines = None
                self._write_meta()

    def __enter__(self) -> RecordingWriter:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class RecordingReader:
    """Frames of a recording directory, in order."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        meta_path = self.path / "meta.json"
        if not meta_path.is_file() or not (self.path / "frames.jsonl").is_file():
            raise DataError(
                f"{self.path} is not a recording (no meta.json / frames.jsonl): fix sensor.recording"
            )
        self.meta = read_meta(meta_path)
        if self.meta.get("schema_version") != SCHEMA_VERSION:
            raise DataError(
                f"{self.path}: recording schema {self.meta.get('schema_version')} != {SCHEMA_VERSION}"
            )
        self.records = read_records(self.path / "frames.jsonl")
        # A killed run leaves a partial last line, and files written by threads after
        # their line: drop that tail (not damage); damage before it is reported per frame.
        self.tail_dropped = 0
        while self.records and (
            "damaged" in self.records[-1] or not self._complete(self.records[-1])
        ):
            self.records.pop()
            self.tail_dropped += 1
        self._backgrounds: dict[str, np.ndarray | None] = {}

    def __len__(self) -> int:
        return len(self.records)

    def _files(self, record: dict) -> list[Path]:
        name = _name(record["index"])
        files = [self.path / "tactile" / f / f"{name}.png" for f in record["tactile"]]
        files += [
            self.path / "gt" / "tactile" / f / f"{name}.npz"
            for f, i in record["tactile"].items()
            if i["gt"]
        ]
        if record["camera"] is not None:
            files += [
                self.path / "camera" / "rgb" / f"{name}.png",
                self.path / "camera" / "depth" / f"{name}.npy",
            ]
            if record["camera"]["mask"]:
                files.append(self.path / "camera" / "mask" / f"{name}.png")
        return files

    def _complete(self, record: dict) -> bool:
        try:
            return all(path.is_file() for path in self._files(record))
        except (KeyError, TypeError, AttributeError):
            return False  # a valid JSON line without a frame's keys

    @property
    def class_names(self) -> list[str] | None:
        """Class list the ground-truth material labels index (None when there are none)."""
        return self.meta.get("class_names") if self.meta.get("has_gt_material") else None

    @property
    def frame_period_s(self) -> float:
        period = self.meta.get("frame_period_s")
        if not isinstance(period, (int, float)) or not period > 0:
            raise DataError(
                f"recording {self.path / 'meta.json'} has no valid frame_period_s ({period!r}); "
                "restore it or record again"
            )
        return float(period)

    def _background(self, finger: str) -> np.ndarray | None:
        if finger not in self._backgrounds:
            path = self.path / "tactile" / finger / "background.png"
            self._backgrounds[finger] = _read_png(path) if path.is_file() else None
        return self._backgrounds[finger]

    def frame(self, position: int) -> Frame:
        """The frame at `position`; DamagedFrame when its line or one of its files is bad."""
        record = self.records[position]
        if "damaged" in record:
            raise DamagedFrame(record["index"], "frames.jsonl", record["damaged"])
        try:
            return self._frame(record)
        except (KeyError, TypeError, AttributeError) as exc:
            raise DamagedFrame(
                int(record.get("index", position)),
                "frames.jsonl",
                f"holds a record without {exc}",
            ) from exc

    def _read(self, index: int, path: Path, read):
        return read_or_damaged(index, path, self.path, read)

    def _frame(self, record: dict) -> Frame:
        index = int(record["index"])
        name = _name(index)
        tactile = {}
        for finger, info in record["tactile"].items():
            gt = {}
            if info["gt"]:
                gt_path = self.path / "gt" / "tactile" / finger / f"{name}.npz"
                gt = self._read(index, gt_path, lambda p, keys=info["gt"]: load_npz(p, keys))
            tactile[finger] = TactileReading(
                finger=finger,
                image=self._read(index, self.path / "tactile" / finger / f"{name}.png", imread_rgb),
                world_T_sensor=np.asarray(info["world_T_sensor"]),
                intrinsics=Intrinsics(**self.meta["digit_intrinsics"][finger]),
                background=self._background(finger),
                gt_contact_mask=gt.get("contact_mask"),
                gt_depth=gt.get("depth"),
                gt_material=gt.get("material"),
            )
        camera = None
        if record["camera"] is not None:
            info = record["camera"]
            camera_dir = self.path / "camera"
            depth = self._read(index, camera_dir / "depth" / f"{name}.npy", np.load)
            mask = None
            if info["mask"]:
                mask = self._read(index, camera_dir / "mask" / f"{name}.png", imread_gray) > 127
            camera = CameraReading(
                rgb=self._read(index, camera_dir / "rgb" / f"{name}.png", imread_rgb),
                depth=depth,
                intrinsics=Intrinsics(**self.meta["camera"]["intrinsics"]),
                world_T_camera=np.asarray(info["world_T_camera"]),
                mask=mask,
                name=info["name"],
            )
        gt_pose = record["gt_world_T_object"]
        joints = record["joint_positions"]
        return Frame(
            index=index,
            time_s=record["time_s"],
            world_T_object=np.asarray(record["world_T_object"]),
            tactile=tactile,
            camera=camera,
            gt_world_T_object=None if gt_pose is None else np.asarray(gt_pose),
            joint_positions=None if joints is None else np.asarray(joints),
        )

    def frames(self) -> Iterator[Frame]:
        for position in range(len(self)):
            yield self.frame(position)
