"""Real DIGIT material data for the classifier (task=collect_tactile sensor=real).

While a person or the hand presses an object of one material against the DIGITs, each
sensor's stream is recorded into the layout the classifier trains on (the same one the
simulated collection writes): `<root>/<sensor>/<material>/<id>.png`,
`<root>/_backgrounds/<sensor>.png` and `<root>/manifest.json`.

Per sensor: the no-contact background is the per-pixel median of the sensor's first
`background_frames` frames (taken by `DigitCamera.open`, so nothing may touch the gel
then); a frame is kept only when the contact gate sees contact against that background,
and only when it differs from the last frame kept for that sensor by at least
`min_change` (see `frame_change`), so a press held still gives one image, not hundreds.
Recording stops when every sensor has `max_images` new images, after `duration_s`, when
every video file has ended, or on Ctrl+C; what was kept so far is written either way.

Appending is the default: new images take ids after the highest id in their folder, a
sensor's `_backgrounds/<sensor>.png` is written only when absent (each session's own
backgrounds go to `_backgrounds/session_<k>/`), and the manifest keeps every session.
This module never imports the simulator: a rig without MuJoCo or pyrender runs it.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.errors import ConfigError, DataError, HardwareError
from neuralfeels_sem.perception.contact import ContactGate
from neuralfeels_sem.sensors.real.digit import DigitCamera

log = logging.getLogger(__name__)

BACKGROUND_DIR = "_backgrounds"
MANIFEST = "manifest.json"
# Frames are compared at a quarter of their size (area average): pixel noise averages out,
# a moved or re-pressed contact still changes many of the 80 x 60 cells.
CHANGE_SCALE = 4


@dataclass
class RecordingSettings:
    """task=collect_tactile's sensor=real settings; their defaults and range checks are
    the task's schema (CollectTactileTaskConfig, configs/sensor_sim.py)."""

    material: str | None
    max_images: int  # new images per sensor
    duration_s: float | None
    min_change: float  # grey levels, see frame_change


@dataclass
class _SensorTally:
    """One sensor's counts in this session and the state its next frame is judged by."""

    next_id: int
    read: int = 0
    contact: int = 0
    duplicates: int = 0
    kept: int = 0
    ended: bool = False  # its video file ran out
    last_kept: np.ndarray | None = field(default=None, repr=False)

    def summary(self) -> dict:
        first = self.next_id - self.kept
        return {
            "frames_read": self.read,
            "contact_frames": self.contact,
            "duplicates_dropped": self.duplicates,
            "kept": self.kept,
            "ids": [first, self.next_id - 1] if self.kept else [],
        }


def frame_change(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean absolute difference of two (320, 240, 3) frames in grey levels (0-255), over
    every channel of both downsampled `CHANGE_SCALE` times by area averaging."""
    return float(np.abs(_small(image) - _small(reference)).mean())


def _small(image: np.ndarray) -> np.ndarray:
    size = (image.shape[1] // CHANGE_SCALE, image.shape[0] // CHANGE_SCALE)
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA).astype(np.float32)


def record_tactile(
    root: Path,
    class_names: list[str],
    cameras: Sequence[DigitCamera],
    gate: ContactGate,
    settings: RecordingSettings,
    clock: Callable[[], float] = time.monotonic,
) -> dict:
    """Record contact frames of `settings.material` from `cameras` into `root`; returns
    the root, the new images per sensor and the set's totals."""
    material = _check_material(settings.material, class_names)
    manifest = _existing_manifest(root, class_names)
    if not cameras:
        raise ConfigError("no DIGIT to record from: list at least one in sensor.digit.fingers")
    _make_root(root)
    started = datetime.now(UTC).isoformat(timespec="seconds")
    session = f"session_{len(manifest['sessions']):03d}"
    opened: list[DigitCamera] = []
    try:
        for camera in cameras:
            camera.open()  # captures the no-contact background
            opened.append(camera)
        _write_backgrounds(root, session, opened)
        tallies = {c.finger: _SensorTally(_next_id(root / c.finger / material)) for c in opened}
        elapsed = _record(root, material, opened, gate, settings, tallies, clock)
    finally:
        for camera in opened:
            camera.close()
    manifest["sessions"].append(
        {
            "session": session,
            "material": material,
            "started_utc": started,
            "duration_s": round(elapsed, 2),
            "sensors": {s: t.summary() for s, t in tallies.items()},
            "contact_gate": asdict(gate),
            "min_change": float(settings.min_change),
            "max_images": int(settings.max_images),
            "command": " ".join(["python", "run.py", *sys.argv[1:]]),
        }
    )
    _write_manifest(root, class_names, manifest)
    new = {s: t.kept for s, t in tallies.items()}
    log.info("kept %d %s images (%s) in %s", sum(new.values()), material, new, root)
    return {"root": str(root), "material": material, "new_images": new, "total": manifest["total"]}


def _record(
    root: Path,
    material: str,
    cameras: list[DigitCamera],
    gate: ContactGate,
    settings: RecordingSettings,
    tallies: dict[str, _SensorTally],
    clock: Callable[[], float],
) -> float:
    """Read the sensors in turn until a stop condition; returns the seconds recorded."""
    start = clock()
    limit = int(settings.max_images)
    progress = tqdm(total=limit * len(cameras), desc=f"recording {material}", unit="img")
    try:
        while True:
            active = [c for c in cameras if not tallies[c.finger].ended]
            active = [c for c in active if tallies[c.finger].kept < limit]
            if not active:
                break
            if settings.duration_s is not None and clock() - start >= settings.duration_s:
                break
            for camera in active:
                tally = tallies[camera.finger]
                if _take(root / camera.finger / material, camera, gate, settings, tally):
                    progress.update(1)
            progress.set_postfix(
                {s: f"{t.kept}/{t.contact}/{t.read}" for s, t in tallies.items()}, refresh=False
            )
    except KeyboardInterrupt:
        log.info("recording stopped by the user; writing what was kept")
    finally:
        progress.close()
    return clock() - start


def _take(
    folder: Path,
    camera: DigitCamera,
    gate: ContactGate,
    settings: RecordingSettings,
    tally: _SensorTally,
) -> bool:
    """Read one frame of `camera`; write it when it is a new contact. True when written."""
    try:
        image = camera.read()
    except HardwareError:
        if not camera.video_file:
            raise
        tally.ended = True  # a video file standing in for the sensor has no more frames
        return False
    tally.read += 1
    if not gate.in_contact(image, camera.background):
        return False
    tally.contact += 1
    small = _small(image)
    last = tally.last_kept
    if last is not None and float(np.abs(small - last).mean()) < settings.min_change:
        tally.duplicates += 1
        return False
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{tally.next_id:05d}.png"
    if not cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR)):
        raise DataError(f"cannot write {path}: check the disk and task.root")
    tally.next_id += 1
    tally.kept += 1
    tally.last_kept = small
    return True


def _check_material(material: str | None, class_names: list[str]) -> str:
    if material is None:
        raise ConfigError(
            f"task.material is not set: pass the pressed object's material, one of {class_names}"
        )
    if material not in class_names:
        raise ConfigError(
            f"task.material={material} is not a class: use one of {class_names} or add it to materials"
        )
    return material


def _existing_manifest(root: Path, class_names: list[str]) -> dict:
    """The real data set's manifest to append to (an empty one for a new root)."""
    if root.exists() and not root.is_dir():
        raise DataError(f"task.root={root} is a file: pass a folder")
    path = root / MANIFEST
    if not path.is_file():
        if root.is_dir() and any(p for p in root.iterdir() if not p.name.startswith(".")):
            raise DataError(
                f"task.root={root} holds files but no {MANIFEST}: pick an empty or a recorded folder"
            )
        return {"sessions": []}
    try:
        manifest = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{path} is not readable JSON ({exc}): fix or remove it") from exc
    if manifest.get("source") != "real":
        raise DataError(
            f"task.root={root} holds a {manifest.get('source', 'unknown')} data set: record real "
            "DIGIT data into its own folder and mix them with dataset.sim_root"
        )
    if manifest.get("classes") != class_names:
        raise DataError(
            f"task.root={root} was recorded with materials={manifest.get('classes')}, not "
            f"{class_names}: use the same materials or another task.root"
        )
    return manifest


def _make_root(root: Path) -> None:
    try:
        (root / BACKGROUND_DIR).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(
            f"task.root={root} cannot be created ({exc.strerror}): pick a writable folder"
        ) from exc


def _next_id(folder: Path) -> int:
    """One past the highest numeric image id in `folder` (0 for a new folder)."""
    ids = [int(p.stem) for p in folder.glob("*.png") if p.stem.isdigit()] if folder.is_dir() else []
    return max(ids, default=-1) + 1


def _write_backgrounds(root: Path, session: str, cameras: list[DigitCamera]) -> None:
    folder = root / BACKGROUND_DIR / session
    folder.mkdir(parents=True, exist_ok=True)
    for camera in cameras:
        bgr = cv2.cvtColor(camera.background, cv2.COLOR_RGB2BGR)
        cv2.imwrite(str(folder / f"{camera.finger}.png"), bgr)
        shared = root / BACKGROUND_DIR / f"{camera.finger}.png"
        if not shared.exists():  # the images already in the set were gated against it
            cv2.imwrite(str(shared), bgr)


def _write_manifest(root: Path, class_names: list[str], manifest: dict) -> None:
    """Counts from the files on disk (so earlier sessions and hand-added images count)."""
    sensors = sorted(
        p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith(("_", "."))
    )
    counts = {s: {m: len(list((root / s / m).glob("*.png"))) for m in class_names} for s in sensors}
    out = {
        "layout": "<root>/<sensor>/<material>/<id>.png; backgrounds in _backgrounds/<sensor>.png",
        "source": "real",
        "classes": class_names,
        "sensors": sensors,
        "counts": counts,
        "total": int(sum(sum(v.values()) for v in counts.values())),
        "image_size": [DIGIT_HEIGHT, DIGIT_WIDTH],
        "sessions": manifest["sessions"],
    }
    manifest.update(out)  # the caller reports the new total
    tmp = root / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(out, indent=2))
    tmp.replace(root / MANIFEST)
