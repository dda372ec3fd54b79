"""FeelSight layout: export our Frames, read them back (jpg is lossy: images within tolerance)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.geometry import OPENGL_T_OPENCV
from neuralfeels_sem.sensors.replay.feelsight import FeelSightReader, export_feelsight
from neuralfeels_sem.sensors.replay.recording import RecordingWriter
from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor
from neuralfeels_sem.sim.kinematics import HandKinematics
from tests.sensors.replay.synthetic_frames import make_frames


def smooth_frames(count: int):
    """Frames whose images are smooth (jpg keeps them close) and whose DIGIT poses follow the hand model."""
    frames = make_frames(count, seed=7)
    kinematics = HandKinematics(world_T_palm=np.eye(4))
    yy, xx = np.mgrid[0:320, 0:240]
    for k, frame in enumerate(frames):
        frame.joint_positions = np.linspace(0.0, 0.5, 16) + 0.05 * k
        poses = kinematics.sensor_poses(frame.joint_positions)
        for finger, reading in frame.tactile.items():
            reading.image = (
                np.stack([xx % 256, yy % 256, (xx + yy + 40 * k) % 256], -1).astype(np.uint8) // 2
                + 60
            )
            reading.world_T_sensor = poses[finger]
        cy, cx = np.mgrid[0:60, 0:80]
        frame.camera.rgb = np.stack([cx * 3, cy * 4, np.full_like(cx, 100 + k)], -1).astype(
            np.uint8
        )
    return frames


def test_export_then_read_gives_the_same_frames(tmp_path) -> None:
    frames = smooth_frames(3)
    assert export_feelsight(frames, tmp_path / "log") == 3
    assert (tmp_path / "log" / "allegro" / "index" / "image" / "2.jpg").is_file()
    assert (tmp_path / "log" / "realsense" / "front-left" / "seg" / "0.jpg").is_file()
    with open(tmp_path / "log" / "data.pkl", "rb") as f:
        data = pickle.load(f)
    assert data["allegro"]["joint_state"].shape == (3, 16)
    assert {"intrinsics", "pose"} <= set(data["realsense"]["front-left"])
    # NeuralFeels' convention on disk: OpenGL camera pose and negative depth.
    np.testing.assert_allclose(
        data["realsense"]["front-left"]["pose"][0] @ OPENGL_T_OPENCV,
        frames[0].camera.world_T_camera,
        atol=1e-12,
    )
    reader = FeelSightReader(tmp_path / "log")
    assert len(reader) == 3 and reader.fingers == ["index", "middle", "ring", "thumb"]
    for original in frames:
        loaded = reader.frame(original.index)
        assert loaded.time_s == original.time_s
        np.testing.assert_array_equal(loaded.world_T_object, original.world_T_object)
        np.testing.assert_array_equal(loaded.gt_world_T_object, original.gt_world_T_object)
        np.testing.assert_array_equal(loaded.joint_positions, original.joint_positions)
        np.testing.assert_allclose(
            loaded.camera.world_T_camera, original.camera.world_T_camera, atol=1e-12
        )
        np.testing.assert_array_equal(loaded.camera.depth, original.camera.depth)
        assert loaded.camera.intrinsics == original.camera.intrinsics
        assert np.abs(loaded.camera.rgb.astype(float) - original.camera.rgb).mean() < 2.0
        assert (
            loaded.camera.mask == original.camera.mask
        ).mean() > 0.9  # random masks blur under jpg
        for finger, reading in original.tactile.items():
            got = loaded.tactile[finger]
            np.testing.assert_allclose(got.world_T_sensor, reading.world_T_sensor, atol=1e-12)
            assert np.abs(got.image.astype(float) - reading.image).mean() < 2.0
            assert (got.gt_contact_mask == reading.gt_contact_mask).mean() > 0.9
            np.testing.assert_array_equal(got.background, loaded.tactile[finger].background)


def test_without_digit_poses_the_reader_uses_the_hand_model(tmp_path) -> None:
    frames = smooth_frames(2)
    export_feelsight(frames, tmp_path / "log")
    with open(tmp_path / "log" / "data.pkl", "rb") as f:
        data = pickle.load(f)
    del data["semanticfeels"]  # a log as NeuralFeels writes it
    with open(tmp_path / "log" / "data.pkl", "wb") as f:
        pickle.dump(data, f)
    reader = FeelSightReader(tmp_path / "log")
    loaded = reader.frame(1)
    assert loaded.gt_world_T_object is None
    for finger, reading in frames[1].tactile.items():
        np.testing.assert_allclose(
            loaded.tactile[finger].world_T_sensor, reading.world_T_sensor, atol=1e-12
        )


def test_replay_sensor_reads_feelsight_and_reports_bad_logs(tmp_path) -> None:
    export_feelsight(smooth_frames(2), tmp_path / "log")
    with ReplaySensor(
        recording=str(tmp_path / "log"), format="feelsight", class_names=["a", "b"]
    ) as sensor:
        assert len(list(sensor.frames())) == 2
    with pytest.raises(DataError, match="no camera 'top'"):
        FeelSightReader(tmp_path / "log", camera="top")
    with pytest.raises(DataError, match="not a FeelSight log"):
        FeelSightReader(tmp_path)
    with pytest.raises(DataError, match="already holds"):
        export_feelsight(smooth_frames(1), tmp_path / "log")


def test_recording_to_feelsight_via_the_reader(tmp_path) -> None:
    frames = smooth_frames(2)
    with RecordingWriter(tmp_path / "rec") as writer:
        for frame in frames:
            writer.write(frame)
    from neuralfeels_sem.sensors.replay.recording import RecordingReader

    reader = RecordingReader(tmp_path / "rec")
    assert export_feelsight(reader.frames(), tmp_path / "log", total=len(reader)) == 2
    assert FeelSightReader(tmp_path / "log").frame(1).tactile["thumb"].image.shape == (320, 240, 3)
