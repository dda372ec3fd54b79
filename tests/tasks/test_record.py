"""task=record: missing hardware ends at once with one line per device; recordings replay identically."""

from __future__ import annotations

import json

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.sensors.replay.feelsight import FeelSightReader
from neuralfeels_sem.sensors.replay.recording import RecordingReader, RecordingWriter
from neuralfeels_sem.tasks import record
from tests.helpers import compose_config, run_cli
from tests.sensors.replay.synthetic_frames import assert_frames_equal, make_frames

CLASSES = list(DEFAULT_MATERIALS)


def test_cli_without_hardware_exits_2_with_one_line_per_device(tmp_path) -> None:
    result = run_cli(
        [
            "task=record",
            "sensor=real",
            f"hydra.run.dir={tmp_path}",
            "sensor.digit.serials.index=D20001",
            "sensor.object_pose=null",  # no ArUco layout on the object: fixed pose
        ]
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    start = result.stderr.index("error: ")
    lines = result.stderr[start + len("error: ") :].strip().splitlines()
    assert len(lines) == 6, lines
    assert lines[0] == (
        "DIGIT index (serial D20001) not found (connected DIGITs: none): connect it or set sensor.digit.serials.index"
    )
    assert [line.split(":")[0] for line in lines[1:4]] == [
        "DIGIT middle",
        "DIGIT ring",
        "DIGIT thumb",
    ]
    assert lines[4].startswith("RealSense front_left") and lines[5].startswith(
        "Allegro hand on socketcan:can0"
    )
    assert not (tmp_path / "recording").exists()


def test_recording_a_replay_reproduces_it_and_exports_feelsight(tmp_path, monkeypatch) -> None:
    frames = make_frames(3, seed=11)
    with RecordingWriter(tmp_path / "source", class_names=CLASSES, frame_period_s=0.1) as writer:
        for frame in frames:
            writer.write(frame)
    monkeypatch.chdir(tmp_path)  # outside Hydra the run directory is the working directory
    cfg = compose_config(
        [
            "task=record",
            "sensor=replay",
            f"sensor.recording={tmp_path / 'source'}",
            "task.out=copy",
            "task.feelsight=true",
        ]
    )
    summary = record.run(cfg)
    assert summary["frames"] == 3 and summary["streams"] == [
        "camera",
        "digit/index",
        "digit/middle",
        "digit/ring",
        "digit/thumb",
    ]
    assert json.loads((tmp_path / "record.json").read_text())["frames"] == 3
    copy = RecordingReader(tmp_path / "copy")
    assert copy.meta["config"]["sensor"]["name"] == "replay"
    for original, replayed in zip(frames, copy.frames()):
        assert_frames_equal(original, replayed)
    assert len(FeelSightReader(tmp_path / "copy_feelsight")) == 3


def test_max_frames_and_duration_stop_the_recording(tmp_path, monkeypatch) -> None:
    with RecordingWriter(tmp_path / "source", class_names=CLASSES) as writer:
        for frame in make_frames(4, seed=12, gt=False, fingers=("index",)):
            writer.write(frame)
    monkeypatch.chdir(tmp_path)
    base = ["task=record", "sensor=replay", f"sensor.recording={tmp_path / 'source'}"]
    assert record.run(compose_config([*base, "task.out=a", "task.max_frames=2"]))["frames"] == 2
    # frames are 0.1 s apart: a 0.25 s recording keeps the first three
    assert record.run(compose_config([*base, "task.out=b", "task.duration_s=0.25"]))["frames"] == 3
