"""A 1-second sim run: recorded, replayed bit-identically, and exported to / read from FeelSight."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hydra.utils import instantiate

from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.sensors.replay.feelsight import FeelSightReader, export_feelsight
from neuralfeels_sem.sensors.replay.recording import RecordingWriter
from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor
from neuralfeels_sem.tasks.record import make_sensor
from tests.helpers import compose_config
from tests.sensors.replay.synthetic_frames import assert_frames_equal


@pytest.fixture(scope="module")
def sim_frames():
    cfg = compose_config(["sensor=sim", "object=plushie", "sensor.duration_s=1.0", "sensor.fps=5"])
    sensor = make_sensor(cfg)
    with sensor:
        frames = list(sensor.frames())
    return frames, list(cfg.materials)


def test_sim_recording_replays_identically(sim_frames, tmp_path) -> None:
    frames, classes = sim_frames
    assert len(frames) == 5 and any(r.in_contact_gt for f in frames for r in f.tactile.values())
    with RecordingWriter(tmp_path / "rec", class_names=classes, frame_period_s=0.2) as writer:
        for frame in frames:
            writer.write(frame)
    with ReplaySensor(recording=str(tmp_path / "rec"), class_names=classes) as replay:
        replayed = list(replay.frames())
    assert len(replayed) == len(frames)
    for original, loaded in zip(frames, replayed):
        assert_frames_equal(original, loaded)


def test_sim_run_through_feelsight(sim_frames, tmp_path) -> None:
    frames, _ = sim_frames
    export_feelsight(frames, tmp_path / "log")
    reader = FeelSightReader(tmp_path / "log")
    for original in frames:
        loaded = reader.frame(original.index)
        np.testing.assert_array_equal(loaded.gt_world_T_object, original.gt_world_T_object)
        np.testing.assert_allclose(
            loaded.camera.world_T_camera, original.camera.world_T_camera, atol=1e-12
        )
        np.testing.assert_array_equal(loaded.camera.depth, original.camera.depth)
        assert np.abs(loaded.camera.rgb.astype(float) - original.camera.rgb).mean() < 3.0
        if original.camera.mask is not None:
            assert (loaded.camera.mask == original.camera.mask).mean() > 0.99
        for finger, reading in original.tactile.items():
            got = loaded.tactile[finger]
            np.testing.assert_allclose(got.world_T_sensor, reading.world_T_sensor, atol=1e-12)
            assert np.abs(got.image.astype(float) - reading.image).mean() < 3.0
            assert (got.gt_contact_mask == reading.gt_contact_mask).mean() > 0.99


def test_cfg_instantiates_sim_like_other_sensors() -> None:
    # Every sensor is a partial completed with obj= and class_names= (task=map treats them alike).
    for option in ("sim", "real", "replay"):
        cfg = compose_config([f"sensor={option}"])
        partial = instantiate(cfg.sensor)
        assert isinstance(partial, functools.partial), option
        sensor = partial(obj=None, class_names=list(cfg.materials))
        assert isinstance(sensor, Sensor) and sensor.name == option
