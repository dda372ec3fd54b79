"""oracles_used: which simulator ground truth a run config leaned on."""

from __future__ import annotations

from neuralfeels_sem.eval.oracles import oracles_used
from tests.helpers import compose_config


def test_the_default_run_lists_mask_and_clean_depth() -> None:
    used = oracles_used(compose_config())
    assert "camera_mask" in used and "noise_free_depth" in used


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
