"""Recording throughput: write and replay frames of 4 DIGITs + a 640x480 RGB-D camera.

A real rig streams frames at ~10 Hz into task=record, so writing must keep up; replay speed
bounds how fast mapping can consume a recording.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sensors.replay.feelsight import export_feelsight
from neuralfeels_sem.sensors.replay.recording import RecordingReader, RecordingWriter

FRAMES = 30


def _frames(count: int) -> list[Frame]:
    """Camera-like smooth images with sensor noise (PNG cost depends on content)."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:320, 0:240]
    cy, cx = np.mgrid[0:480, 0:640]
    intr = Intrinsics(fx=615.0, fy=615.0, cx=319.5, cy=239.5, width=640, height=480)
    frames = []
    for k in range(count):
        tactile = {}
        for finger in FINGERS:
            base = np.stack([xx // 2 + 60, yy // 3 + 50, (xx + yy + k) % 200], -1)
            image = np.clip(base + rng.normal(0, 2, base.shape), 0, 255).astype(np.uint8)
            tactile[finger] = TactileReading(
                finger, image, np.eye(4), DIGIT_INTRINSICS, background=image
            )
        rgb = np.clip(
            np.stack([cx // 3, cy // 2, np.full_like(cx, 90)], -1)
            + rng.normal(0, 2, (480, 640, 3)),
            0,
            255,
        )
        depth = (0.4 + 0.1 * np.sin(cx / 50.0) + rng.normal(0, 0.001, (480, 640))).astype(
            np.float32
        )
        camera = CameraReading(rgb.astype(np.uint8), depth, intr, np.eye(4))
        frames.append(Frame(k, 0.1 * k, np.eye(4), tactile, camera, joint_positions=np.zeros(16)))
    return frames


def run() -> dict:
    frames = _frames(FRAMES)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec"
        start = time.perf_counter()
        with RecordingWriter(path) as writer:
            for frame in frames:
                writer.write(frame)
        write_s = time.perf_counter() - start
        size_mb = sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) / 1e6
        start = time.perf_counter()
        reader = RecordingReader(path)
        replayed = list(reader.frames())
        read_s = time.perf_counter() - start
        assert len(replayed) == FRAMES
        start = time.perf_counter()
        export_feelsight(replayed, Path(tmp) / "feelsight", total=FRAMES)
        export_s = time.perf_counter() - start
    return {
        "frames": FRAMES,
        "content": "4 DIGIT 320x240 RGB + camera 640x480 RGB + float32 depth",
        "write_fps": round(FRAMES / write_s, 2),
        "read_fps": round(FRAMES / read_s, 2),
        "feelsight_export_fps": round(FRAMES / export_s, 2),
        "disk_mb_per_frame": round(size_mb / FRAMES, 3),
    }
