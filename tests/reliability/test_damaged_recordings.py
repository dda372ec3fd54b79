"""Damaged recordings and FeelSight logs: each bad frame is reported with its index, skipped
and counted (or, with on_damaged_frame=stop, ends the replay in one line); a damaged
whole-recording file is one line; a partial tail is dropped and reported once. The
recording itself is never changed by replaying it."""

from __future__ import annotations

import json
import logging
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from hydra.utils import instantiate

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.sensors.replay.feelsight import export_feelsight
from neuralfeels_sem.sensors.replay.recording import RecordingWriter
from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor
from tests.helpers import TOY_MAPPING, compose_config, run_cli
from tests.reliability.checks import tree_digest
from tests.sensors.replay.synthetic_frames import make_frames

FRAMES = 8
DAMAGED = 3  # the frame each per-frame case damages (the middle of the recording)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> dict[str, Path]:
    """An 8-frame native recording (two fingers, sim ground truth) and its FeelSight export."""
    root = tmp_path_factory.mktemp("pristine")
    frames = make_frames(FRAMES, seed=11, fingers=("index", "thumb"))
    with RecordingWriter(root / "native", frame_period_s=0.1, workers=0) as writer:
        for frame in frames:
            writer.write(frame)
    export_feelsight(frames, root / "feelsight")
    return {"native": root / "native", "feelsight": root / "feelsight"}


def _copy(pristine: dict[str, Path], kind: str, tmp_path: Path) -> Path:
    return Path(shutil.copytree(pristine[kind], tmp_path / kind))


def _line(path: Path, number: int, text: str) -> None:
    lines = path.read_text().splitlines()
    lines[number] = text
    path.write_text("\n".join(lines) + "\n")


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:60])


N = f"{DAMAGED:06d}"
# case -> (format, damage(recording dir), file named in the report)
FRAME_DAMAGE: dict[str, tuple[str, Callable[[Path], None], str]] = {
    "jsonl_garbage_line": (
        "native",
        lambda d: _line(d / "frames.jsonl", DAMAGED, '{"index": 3, "tact'),
        "frames.jsonl",
    ),
    "jsonl_record_without_keys": (
        "native",
        lambda d: _line(d / "frames.jsonl", DAMAGED, '{"index": 3}'),
        "frames.jsonl",
    ),
    "jsonl_not_an_object": (
        "native",
        lambda d: _line(d / "frames.jsonl", DAMAGED, "[1, 2, 3]"),
        "frames.jsonl",
    ),
    "tactile_png_missing": (
        "native",
        lambda d: (d / "tactile" / "index" / f"{N}.png").unlink(),
        f"tactile/index/{N}.png",
    ),
    "tactile_png_truncated": (
        "native",
        lambda d: _truncate(d / "tactile" / "thumb" / f"{N}.png"),
        f"tactile/thumb/{N}.png",
    ),
    "depth_npy_missing": (
        "native",
        lambda d: (d / "camera" / "depth" / f"{N}.npy").unlink(),
        f"camera/depth/{N}.npy",
    ),
    "depth_npy_truncated": (
        "native",
        lambda d: _truncate(d / "camera" / "depth" / f"{N}.npy"),
        f"camera/depth/{N}.npy",
    ),
    "rgb_png_empty": (
        "native",
        lambda d: (d / "camera" / "rgb" / f"{N}.png").write_bytes(b""),
        f"camera/rgb/{N}.png",
    ),
    "mask_png_garbage": (
        "native",
        lambda d: (d / "camera" / "mask" / f"{N}.png").write_bytes(b"not a png"),
        f"camera/mask/{N}.png",
    ),
    "gt_npz_truncated": (
        "native",
        lambda d: _truncate(d / "gt" / "tactile" / "index" / f"{N}.npz"),
        f"gt/tactile/index/{N}.npz",
    ),
    "feelsight_digit_jpg_missing": (
        "feelsight",
        lambda d: (d / "allegro" / "thumb" / "image" / f"{DAMAGED}.jpg").unlink(),
        f"allegro/thumb/image/{DAMAGED}.jpg",
    ),
    "feelsight_camera_jpg_empty": (
        "feelsight",
        lambda d: (d / "realsense" / "front-left" / "image" / f"{DAMAGED}.jpg").write_bytes(b""),
        f"realsense/front-left/image/{DAMAGED}.jpg",
    ),
}


def _replay(recording: Path, kind: str, policy: str = "skip") -> tuple[list[int], ReplaySensor]:
    sensor = ReplaySensor(recording=str(recording), format=kind, on_damaged_frame=policy)
    with sensor:
        indices = [frame.index for frame in sensor.frames()]
    return indices, sensor


@pytest.mark.parametrize("case", list(FRAME_DAMAGE))
def test_a_damaged_frame_is_skipped_reported_and_counted(
    pristine, tmp_path, caplog, case: str
) -> None:
    kind, damage, file = FRAME_DAMAGE[case]
    recording = _copy(pristine, kind, tmp_path)
    damage(recording)
    before = tree_digest(recording)
    with caplog.at_level(logging.WARNING):
        indices, sensor = _replay(recording, kind)
    # every other frame, after the damaged one too: no silent early end
    assert indices == [i for i in range(FRAMES) if i != DAMAGED]
    report = sensor.damage_report()
    assert report["frames_skipped"] == 1 and report["tail_dropped"] == 0
    assert report["damaged"][0]["index"] == DAMAGED and report["damaged"][0]["file"] == file
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and f"frame {DAMAGED}: {file}" in warnings[0]
    assert tree_digest(recording) == before


@pytest.mark.parametrize("case", ["jsonl_garbage_line", "depth_npy_missing"])
def test_on_damaged_frame_stop_ends_in_one_line(pristine, tmp_path, case: str) -> None:
    kind, damage, file = FRAME_DAMAGE[case]
    recording = _copy(pristine, kind, tmp_path)
    damage(recording)
    with pytest.raises(DataError) as caught:
        _replay(recording, kind, policy="stop")
    message = str(caught.value)
    assert caught.value.exit_code == 2 and "\n" not in message
    assert f"frame {DAMAGED}: {file}" in message and "sensor.on_damaged_frame=skip" in message


def _cut_last_line(d: Path) -> None:
    text = (d / "frames.jsonl").read_text()
    (d / "frames.jsonl").write_text(text[: text.rstrip("\n").rfind("\n") + 40])


def _drop_last_files(d: Path) -> None:
    for path in d.rglob(f"{FRAMES - 1:06d}.*"):
        path.unlink()
    (d / "camera" / "depth" / f"{FRAMES - 2:06d}.npy").unlink()


TAILS = {"partial_last_line": (_cut_last_line, 1), "last_files_unwritten": (_drop_last_files, 2)}


@pytest.mark.parametrize("case", list(TAILS))
def test_a_partial_tail_is_dropped_and_reported_once(pristine, tmp_path, caplog, case) -> None:
    damage, dropped = TAILS[case]
    recording = _copy(pristine, "native", tmp_path)
    damage(recording)
    with caplog.at_level(logging.WARNING):
        indices, sensor = _replay(recording, "native")
    assert indices == list(range(FRAMES - dropped))
    assert sensor.damage_report()["tail_dropped"] == dropped
    assert sensor.damage_report()["frames_skipped"] == 0
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and f"last {dropped} record(s) are incomplete" in warnings[0]


# case -> (format, damage, words the one-line error holds)
WHOLE_FILE = {
    "meta_json_truncated": (
        "native",
        lambda d: _truncate(d / "meta.json"),
        ["meta.json is damaged", "record again"],
    ),
    "meta_json_not_an_object": (
        "native",
        lambda d: (d / "meta.json").write_text("[1, 2]"),
        ["meta.json is not a JSON object"],
    ),
    "meta_json_without_frame_period": (
        "native",
        lambda d: (d / "meta.json").write_text('{"schema_version": 1}'),
        ["meta.json has no valid frame_period_s"],
    ),
    "feelsight_data_pkl_truncated": (
        "feelsight",
        lambda d: _truncate(d / "data.pkl"),
        ["data.pkl is damaged"],
    ),
    "feelsight_depth_npz_missing": (
        "feelsight",
        lambda d: (d / "realsense" / "front-left" / "depth.npz").unlink(),
        ["depth.npz is missing or damaged"],
    ),
    "feelsight_background_missing": (
        "feelsight",
        lambda d: (d / "allegro" / "index" / "image" / "0.jpg").unlink(),
        ["allegro/index/image/0.jpg is missing", "background"],
    ),
}


@pytest.mark.parametrize("case", list(WHOLE_FILE))
def test_a_damaged_recording_file_is_one_line(pristine, tmp_path, case: str) -> None:
    kind, damage, words = WHOLE_FILE[case]
    recording = _copy(pristine, kind, tmp_path)
    damage(recording)
    before = tree_digest(recording)
    with pytest.raises(DataError) as caught:
        _replay(recording, kind)
    assert caught.value.exit_code == 2 and "\n" not in str(caught.value)
    for word in words:
        assert word in str(caught.value), (word, str(caught.value))
    assert tree_digest(recording) == before


@pytest.fixture(scope="module")
def sim_recording(tmp_path_factory) -> Path:
    """Six small sim frames (ground truth kept) recorded as task=record writes them."""
    cfg = compose_config(SIM)
    sensor = build_sensor(cfg.sensor, instantiate(cfg.object), list(cfg.materials))
    path = tmp_path_factory.mktemp("sim") / "recording"
    with sensor, RecordingWriter(path, list(cfg.materials), sensor.frame_period_s) as writer:
        for frame in sensor.frames():
            writer.write(frame)
    return path


SIM = [
    "sensor.rgbd.width=160",
    "sensor.rgbd.height=120",
    "sensor.duration_s=1.2",
    "sensor.fps=5",
]
SMALL_MAP = [
    "mapping.mapper.camera_mask=gt",
    "mapping.mapper.tactile_depth.source=gt",
    "classifier=oracle",
    *TOY_MAPPING,
]


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["skip", "stop"])
def test_a_map_run_over_a_damaged_recording(sim_recording, tmp_path, policy: str) -> None:
    """skip: exit 0, one warning naming the frame, metrics.json counts it; stop: exit 2
    in one line. The recording is unchanged either way."""
    recording = Path(shutil.copytree(sim_recording, tmp_path / "recording"))
    _line(recording / "frames.jsonl", 2, "{damaged")
    before = tree_digest(recording)
    run_dir = tmp_path / "run"
    args = [
        *SMALL_MAP,
        "sensor=replay",
        f"sensor.recording={recording}",
        f"sensor.on_damaged_frame={policy}",
        f"hydra.run.dir={run_dir}",
    ]
    result = run_cli(args, timeout=600)
    assert tree_digest(recording) == before
    if policy == "stop":
        # The progress bar shares stderr: every other segment is the bar's, and the bar is
        # closed first so the error starts its own line.
        segments = [s for s in re.split(r"[\r\n]", result.stderr) if s.strip()]
        errors = [s for s in segments if not s.startswith("map:")]
        assert result.returncode == 2 and "Traceback" not in result.stderr
        assert len(errors) == 1 and errors[0].startswith("error: "), result.stderr[-2000:]
        assert "frame 2: frames.jsonl" in errors[0] and "on_damaged_frame=skip" in errors[0]
        return
    assert result.returncode == 0, result.stderr[-2000:]
    output = result.stdout + result.stderr
    assert "Traceback" not in output
    assert output.count("skipping damaged frame") == 1 and "frame 2: frames.jsonl" in output
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["replay"]["frames_skipped"] == 1
    assert metrics["replay"]["damaged"][0]["index"] == 2
    assert metrics["frames_total"] == 6  # the frames after the damaged line were mapped
