"""oracles_used: which simulator ground truth a run config leaned on."""

from __future__ import annotations

import json

from omegaconf import OmegaConf

from neuralfeels_sem.eval.oracles import oracles_used
from tests.helpers import compose_config


def test_the_default_run_uses_only_the_pose_oracle() -> None:
    assert oracles_used(compose_config()) == ["object_pose"]
    assert oracles_used(compose_config(["sensor=real"])) == []


def test_the_oracle_preset_lists_every_perception_oracle() -> None:
    assert oracles_used(compose_config(["perception=oracle"])) == [
        "object_pose",
        "camera_mask",
        "tactile_contact_depth",
        "noise_free_depth",
    ]
    for preset, oracle in (
        ("oracle_camera_mask", "camera_mask"),
        ("oracle_tactile_depth", "tactile_contact_depth"),
        ("oracle_depth", "noise_free_depth"),
    ):
        assert oracles_used(compose_config([f"perception={preset}"])) == ["object_pose", oracle]


def test_each_source_can_be_set_alone() -> None:
    config = compose_config(["mapping.mapper.camera_mask=gt", "sensor.rgbd.depth_noise=none"])
    assert oracles_used(config) == ["object_pose", "camera_mask", "noise_free_depth"]


def test_segmentation_and_realsense_noise_are_no_oracles() -> None:
    config = compose_config(
        ["mapping.mapper.camera_mask=segment", "sensor.rgbd.depth_noise=realsense"]
    )
    used = oracles_used(config)
    assert "camera_mask" not in used and "noise_free_depth" not in used


def test_configs_saved_with_the_former_keys_still_name_their_oracles() -> None:
    saved = {
        "sensor": {"name": "sim", "rgbd": {"depth_noise_std": 0.0}},
        "mapping": {"pose": "gt", "mapper": {"use_camera_mask": True}},
    }
    assert {"camera_mask", "noise_free_depth"} <= set(oracles_used(saved))
    saved["sensor"]["rgbd"]["depth_noise_std"] = 0.002
    saved["mapping"]["mapper"]["use_camera_mask"] = False
    assert not {"camera_mask", "noise_free_depth"} & set(oracles_used(saved))


def _recording(path, sensor: dict | None) -> str:
    """A recording directory holding only the meta.json that names its sensor config."""
    path.mkdir()
    meta = {"schema_version": 1} if sensor is None else {"config": {"sensor": sensor}}
    (path / "meta.json").write_text(json.dumps(meta))
    return str(path)


def test_a_replay_of_a_simulated_recording_names_the_simulators_oracles(tmp_path) -> None:
    simulated = OmegaConf.to_container(compose_config(["sensor.rgbd.depth_noise=none"]).sensor)
    first = _recording(tmp_path / "sim", simulated)
    replay = compose_config(["sensor=replay", f"sensor.recording={first}"])
    assert oracles_used(replay) == ["object_pose", "noise_free_depth"]
    # A recording of that replay is followed back to the simulator.
    again = _recording(tmp_path / "again", OmegaConf.to_container(replay.sensor))
    assert oracles_used(compose_config(["sensor=replay", f"sensor.recording={again}"])) == [
        "object_pose",
        "noise_free_depth",
    ]


def test_a_replay_that_does_not_say_it_was_simulated_has_no_oracles(tmp_path) -> None:
    rig = OmegaConf.to_container(compose_config(["sensor=real"]).sensor)
    for recording in (
        _recording(tmp_path / "rig", rig),
        _recording(tmp_path / "no_config", None),
        str(tmp_path / "missing"),
    ):
        assert (
            oracles_used(compose_config(["sensor=replay", f"sensor.recording={recording}"])) == []
        )
    simulated = _recording(tmp_path / "sim", OmegaConf.to_container(compose_config().sensor))
    feelsight = ["sensor=replay", "sensor.format=feelsight", f"sensor.recording={simulated}"]
    assert oracles_used(compose_config(feelsight)) == []
