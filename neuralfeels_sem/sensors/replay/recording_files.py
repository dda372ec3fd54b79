"""Reading a recording's files: meta.json, the records of frames.jsonl, images and arrays.

The per-frame readers return None (images) or raise (arrays) on a bad file; the
RecordingReader turns either into a DamagedFrame naming the frame (damage.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.errors import DataError


def imread_rgb(path: Path) -> np.ndarray | None:
    """RGB image, or None when OpenCV cannot decode the file."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return None if image is None else cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def imread_gray(path: Path) -> np.ndarray | None:
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


def load_npz(path: Path, keys: list[str]) -> dict[str, np.ndarray]:
    with np.load(path) as data:
        return {key: data[key] for key in keys}


def read_meta(path: Path) -> dict:
    """meta.json as a dict; DataError in one line when it is truncated or not an object."""
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(
            f"recording {path} is damaged ({exc.__class__.__name__} at character "
            f"{getattr(exc, 'pos', '?')}); restore it from a backup or record again"
        ) from exc
    if not isinstance(meta, dict):
        raise DataError(f"recording {path} is not a JSON object; restore it or record again")
    return meta


def recorded_sensor_config(recording: Path) -> dict | None:
    """The sensor config a recording was made with (meta.json's `config.sensor`, written by
    task=record); None when the recording, its meta.json or that key is missing or unreadable."""
    meta_path = Path(recording) / "meta.json"
    if not meta_path.is_file():
        return None
    try:
        meta = read_meta(meta_path)
    except DataError:
        return None
    config = meta.get("config")
    sensor = config.get("sensor") if isinstance(config, dict) else None
    return sensor if isinstance(sensor, dict) else None


def read_records(path: Path) -> list[dict]:
    """frames.jsonl's records; a damaged line becomes {"index": its guessed index,
    "damaged": why} (frames are numbered consecutively, so it is the one after the last)."""
    records: list[dict] = []
    with open(path, errors="replace") as lines:
        for number, line in enumerate(lines, start=1):
            guess = int(records[-1].get("index", -1)) + 1 if records else 0
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                record = None
            if not isinstance(record, dict) or not isinstance(record.get("index"), int):
                record = {"index": guess, "damaged": f"line {number} is not a frame record"}
            records.append(record)
    return records
