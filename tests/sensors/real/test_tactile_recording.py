"""task=collect_tactile sensor=real: contact frames from DIGIT video files into the data set layout."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.perception.classifier.dataset import load_backgrounds, scan_dataset
from neuralfeels_sem.sensors.real.tactile_recording import frame_change
from neuralfeels_sem.tasks.collect_tactile import run
from tests.helpers import compose_config
from tests.perception.synthetic_tactile import CLASSES, background, pressed

BACKGROUND_FRAMES = 3


def write_video(path: Path, images: list[np.ndarray]) -> str:
    """An MJPG video of raw landscape DIGIT frames that DigitCamera turns back into `images` (RGB)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (320, 240))
    assert writer.isOpened()
    for image in images:
        # The inverse of digit_raw_to_image: portrait RGB -> the stream's landscape BGR.
        writer.write(cv2.transpose(cv2.flip(cv2.cvtColor(image, cv2.COLOR_RGB2BGR), 0)))
    writer.release()
    return str(path)


def stream(empty: np.ndarray, first: np.ndarray, second: np.ndarray) -> list[np.ndarray]:
    """Background frames, no contact, a press held still, a lift, another press, the first again.

    Contact frames: 3 x first (1 kept, 2 duplicates), 2 x second (1 kept, 1 duplicate),
    1 x first (kept: it differs from the last kept, the second press).
    """
    return (
        [empty] * (BACKGROUND_FRAMES + 2)
        + [first] * 3
        + [empty]
        + [second] * 2
        + [first]
        + [empty] * 2
    )


def cfg(root: Path, videos: dict[str, str], *extra: str):
    fingers = ",".join(videos)
    return compose_config(
        [
            "task=collect_tactile",
            "sensor=real",
            f"task.root={root}",
            f"sensor.digit.fingers=[{fingers}]",
            f"sensor.digit.background_frames={BACKGROUND_FRAMES}",
            *(f"+sensor.digit.video_files.{f}={v}" for f, v in videos.items()),
            *extra,
        ]
    )


@pytest.fixture
def synthetic_videos(tmp_path: Path) -> dict[str, str]:
    rng = np.random.default_rng(0)
    videos = {}
    for s, finger in enumerate(("index", "thumb")):
        frames = stream(background(s), pressed(s, 1, rng), pressed(s, 1, rng))
        videos[finger] = write_video(tmp_path / f"{finger}.avi", frames)
    return videos


def check_session(root: Path, fingers: list[str], material: str, ids: list[str]) -> dict:
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["source"] == "real" and manifest["classes"] == CLASSES
    for finger in fingers:
        files = sorted(p.name for p in (root / finger / material).glob("*.png"))
        assert files == ids
        assert cv2.imread(str(root / finger / material / ids[0])).shape == (320, 240, 3)
        assert manifest["counts"][finger][material] == len(ids)
    assert set(load_backgrounds(root)) == set(fingers)
    return manifest


def test_keeps_only_new_contact_frames(tmp_path: Path, synthetic_videos) -> None:
    root = tmp_path / "real"
    result = run(cfg(root, synthetic_videos, "task.material=metal"))
    assert result["new_images"] == {"index": 3, "thumb": 3}
    manifest = check_session(
        root, ["index", "thumb"], "metal", ["00000.png", "00001.png", "00002.png"]
    )
    session = manifest["sessions"][0]
    assert session["material"] == "metal"
    assert session["sensors"]["index"] == {
        "frames_read": 11,  # 14 frames in the video, 3 taken as the background
        "contact_frames": 6,
        "duplicates_dropped": 3,
        "kept": 3,
        "ids": [0, 2],
    }
    # The trainer reads the set as it is.
    samples = scan_dataset(root, CLASSES, require_all_classes=False)
    assert len(samples) == 6 and {s.label for s in samples} == {CLASSES.index("metal")}


def test_appending_keeps_earlier_images(tmp_path: Path, synthetic_videos) -> None:
    root = tmp_path / "real"
    run(cfg(root, synthetic_videos, "task.material=metal"))
    before = {p: p.read_bytes() for p in root.rglob("*.png")}
    run(cfg(root, synthetic_videos, "task.material=metal", "task.max_images=2"))
    run(cfg(root, synthetic_videos, "task.material=wood"))
    for path, data in before.items():
        assert path.read_bytes() == data, f"{path} was overwritten"
    manifest = check_session(root, ["index", "thumb"], "metal", [f"{i:05d}.png" for i in range(5)])
    assert [s["material"] for s in manifest["sessions"]] == ["metal", "metal", "wood"]
    assert manifest["sessions"][1]["sensors"]["thumb"]["ids"] == [3, 4]  # stopped at max_images
    assert manifest["counts"]["index"]["wood"] == 3
    assert manifest["total"] == 2 * (5 + 3)


def test_refuses_bad_material_and_foreign_sets(tmp_path: Path, synthetic_videos) -> None:
    root = tmp_path / "real"
    with pytest.raises(ConfigError, match=r"task.material=gold is not a class"):
        run(cfg(root, synthetic_videos, "task.material=gold"))
    with pytest.raises(ConfigError, match=r"task.material is not set"):
        run(cfg(root, synthetic_videos))
    assert not root.exists()  # refused before anything was written
    (root).mkdir()
    (root / "manifest.json").write_text(json.dumps({"source": "sim", "classes": CLASSES}))
    with pytest.raises(DataError, match="holds a sim data set"):
        run(cfg(root, synthetic_videos, "task.material=metal"))


def test_real_digit_frames(tmp_path: Path, shared_data: Path) -> None:
    folder = shared_data / "digit_real"
    empty, first, second = (
        cv2.imread(str(folder / name))[..., ::-1].copy()
        for name in (
            "backgrounds/aurova_bg_1.png",
            "contact/ycb_grasp_1.png",
            "contact/ycb_grasp_2.png",
        )
    )
    assert frame_change(first, second) > 3.0  # two grasps are different images
    video = write_video(tmp_path / "index.avi", stream(empty, first, second))
    root = tmp_path / "real"
    result = run(cfg(root, {"index": video}, "task.material=plastic"))
    assert result["new_images"] == {"index": 3}
    manifest = check_session(root, ["index"], "plastic", ["00000.png", "00001.png", "00002.png"])
    assert manifest["sessions"][0]["sensors"]["index"]["duplicates_dropped"] == 3
