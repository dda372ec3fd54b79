"""Record Frames, read them back identically, and replay them through ReplaySensor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.sensors.replay import replay_sensor as replay_module
from neuralfeels_sem.sensors.replay.recording import RecordingReader, RecordingWriter
from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor
from tests.sensors.replay.synthetic_frames import assert_frames_equal, make_frames

CLASSES = list(DEFAULT_MATERIALS)


def write(path, frames, **kwargs) -> None:
    with RecordingWriter(path, class_names=CLASSES, frame_period_s=0.1, **kwargs) as writer:
        for frame in frames:
            writer.write(frame, stamps={"camera": frame.time_s})


def test_every_field_round_trips_bit_exactly(tmp_path) -> None:
    frames = make_frames(3, seed=1)
    write(tmp_path / "rec", frames, calibration={"world_T_palm": np.eye(4).tolist()})
    reader = RecordingReader(tmp_path / "rec")
    assert len(reader) == 3 and reader.class_names == CLASSES and reader.frame_period_s == 0.1
    for original, loaded in zip(frames, reader.frames()):
        assert_frames_equal(original, loaded)
    meta = json.loads((tmp_path / "rec" / "meta.json").read_text())
    assert meta["num_frames"] == 3 and meta["calibration"]["world_T_palm"][0] == [
        1.0,
        0.0,
        0.0,
        0.0,
    ]
    assert sorted(p.name for p in (tmp_path / "rec" / "tactile" / "index").iterdir())[:2] == [
        "000000.png",
        "000001.png",
    ]
    assert reader.records[1]["stamps"] == {"camera": frames[1].time_s}


def test_frames_without_ground_truth_or_camera(tmp_path) -> None:
    frames = make_frames(2, seed=2, gt=False, fingers=("thumb",))
    frames[1].camera = None
    frames[1].joint_positions = None
    write(tmp_path / "rec", frames)
    reader = RecordingReader(tmp_path / "rec")
    assert reader.class_names is None  # no material labels recorded: any class list may replay it
    for original, loaded in zip(frames, reader.frames()):
        assert_frames_equal(original, loaded)


def test_a_truncated_recording_keeps_its_complete_frames(tmp_path) -> None:
    write(tmp_path / "rec", make_frames(3, seed=3, gt=False))
    lines = (tmp_path / "rec" / "frames.jsonl").read_text().splitlines()
    (tmp_path / "rec" / "frames.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    assert len(RecordingReader(tmp_path / "rec")) == 2
    # a frame whose image files were never written (killed before the writer threads finished)
    (tmp_path / "rec" / "camera" / "depth" / "000001.npy").unlink()
    assert len(RecordingReader(tmp_path / "rec")) == 1


def test_writer_refuses_to_overwrite(tmp_path) -> None:
    write(tmp_path / "rec", make_frames(1, gt=False))
    with pytest.raises(DataError, match="already holds"):
        RecordingWriter(tmp_path / "rec").open()


def test_replay_sensor_yields_identical_frames(tmp_path) -> None:
    frames = make_frames(4, seed=4)
    write(tmp_path / "rec", frames)
    sensor = ReplaySensor(recording=str(tmp_path / "rec"), class_names=CLASSES, max_frames=3)
    with sensor:
        replayed = list(sensor.frames())
        assert len(sensor) == 3 and sensor.frame_period_s == 0.1
    assert len(replayed) == 3
    for original, loaded in zip(frames, replayed):
        assert_frames_equal(original, loaded)


def test_realtime_replay_waits_for_the_recorded_times(tmp_path, monkeypatch) -> None:
    frames = make_frames(3, seed=5, gt=False, fingers=("index",))
    write(tmp_path / "rec", frames)
    clock = {"now": 100.0}
    sleeps = []
    monkeypatch.setattr(replay_module.time, "monotonic", lambda: clock["now"])

    def fake_sleep(seconds: float) -> None:
        sleeps.append(seconds)
        clock["now"] += seconds

    monkeypatch.setattr(replay_module.time, "sleep", fake_sleep)
    with ReplaySensor(recording=str(tmp_path / "rec"), pace="realtime") as sensor:
        list(sensor.frames())
    expected = [frames[i].time_s - frames[i - 1].time_s for i in (1, 2)]
    np.testing.assert_allclose(sleeps, expected, rtol=0, atol=1e-12)
    with ReplaySensor(recording=str(tmp_path / "rec"), pace="offline") as sensor:
        sleeps.clear()
        list(sensor.frames())
    assert sleeps == []


def test_replay_errors_are_one_line(tmp_path) -> None:
    with pytest.raises(ConfigError, match="sensor.recording"):
        ReplaySensor().open()
    with pytest.raises(DataError, match="not found"):
        ReplaySensor(recording=str(tmp_path / "nope")).open()
    write(tmp_path / "rec", make_frames(1, seed=6))
    with pytest.raises(ConfigError, match="materials"):
        ReplaySensor(recording=str(tmp_path / "rec"), class_names=["a", "b"]).open()
