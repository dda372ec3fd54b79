"""Sensor.hand_model(): the kinematics camera segmentation renders, per backend."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.sensors.real.allegro_can import AllegroCAN
from neuralfeels_sem.sensors.real.real_sensor import RealSensor
from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor
from neuralfeels_sem.sensors.sim import SimSensor
from tests.sensors.real.fake_allegro import FakeAllegro
from tests.sim.shapes import CLASSES, two_material_sphere


def test_sim_hand_model_matches_the_rendered_hand() -> None:
    """The scene-free model at a frame's joints puts every link where the camera saw it."""
    sensor = SimSensor(two_material_sphere(), class_names=CLASSES, duration_s=0.3, seed=0)
    with sensor:
        frame = sensor.frame_at(2)
        model = sensor.hand_model()
        rendered = sensor.rig.scene.hand_meshes()
        modelled = model.link_meshes(frame.joint_positions)
        np.testing.assert_array_equal(model.world_T_palm, sensor.rig.scene.world_T_palm)
    assert len(modelled) == len(rendered)
    for (mesh_a, pose_a), (mesh_b, pose_b) in zip(modelled, rendered, strict=True):
        np.testing.assert_allclose(pose_a, pose_b, atol=1e-6)
        np.testing.assert_allclose(mesh_a.extents, mesh_b.extents, atol=1e-9)


def test_real_hand_model_is_the_configured_kinematics() -> None:
    with FakeAllegro("hand_model_test", q=np.zeros(16)):
        sensor = RealSensor(
            hand=AllegroCAN(channel="hand_model_test", interface="virtual", timeout_s=0.5),
            duration_s=0.1,
        )
        assert sensor.hand_model() is None  # built by open()
        with sensor:
            model = sensor.hand_model()
            assert model.joint_limits.shape == (16, 2)
            assert len(model.link_meshes(np.zeros(16))) > 16


def test_replay_of_a_recording_without_a_hand_model_has_none(tmp_path) -> None:
    # A recording written without a hand model (hand_model: null in meta.json); the
    # replay of one with a model is tests/sensors/replay/test_stripped_replay.py.
    from neuralfeels_sem.sensors.replay.recording import RecordingWriter
    from tests.sensors.replay.synthetic_frames import make_frames

    with RecordingWriter(tmp_path / "rec", workers=0) as writer:
        for frame in make_frames(2, seed=3):
            writer.write(frame)
    assert ReplaySensor(recording=str(tmp_path / "rec")).hand_model() is None
