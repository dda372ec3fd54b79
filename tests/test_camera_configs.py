"""The camera keys of issue #19 compose, validate and reach their classes; bad values fail clearly."""

from __future__ import annotations

import pytest
from hydra.utils import instantiate

from neuralfeels_sem.configs import to_config, validate_config
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.mapping.mapper import MapperConfig
from tests.helpers import compose_config

GOOD = [
    "mapping.mapper.camera_mask=segment",
    "mapping.mapper.segmentation.workspace_min=[-0.02,-0.1,-0.05]",
    "mapping.mapper.segmentation.hand_margin_m=0.006",
    "mapping.mapper.segmentation.hand_dilation_px=0",
    "mapping.mapper.segmentation.plane_min_extent_m=0.2",
    "mapping.mapper.segmentation.cluster_merge_m=0.01",
    "sensor.rgbd.depth_noise=realsense",
    "sensor.rgbd.realsense.subpixel=0.1",
    "sensor.rgbd.realsense.dropout=0",
    "sensor.rgbd.table_height=null",
    "sensor.rgbd.backdrop_distance=1.2",
    "sensor.rgbd.mount=false",
]


def test_every_camera_key_composes_and_reaches_its_class() -> None:
    cfg = compose_config(GOOD)
    validate_config(cfg)
    mapper = to_config(MapperConfig, cfg.mapping.mapper)
    assert mapper.camera_mask == "segment"
    assert mapper.segmentation.hand_margin_m == 0.006
    assert mapper.segmentation.workspace_min == [-0.02, -0.1, -0.05]
    sensor = instantiate(cfg.sensor)(obj=None)
    assert sensor.rgbd_options["depth_noise"] == "realsense"
    assert sensor.rgbd_options["realsense"]["subpixel"] == 0.1
    assert sensor.rgbd_options["table_height"] is None and sensor.rgbd_options["mount"] is False


@pytest.mark.parametrize(
    "override",
    [
        "mapping.mapper.camera_mask=sam",
        "mapping.mapper.segmentation.workspace_max=[-0.5,0.15,0.2]",
        "mapping.mapper.segmentation.plane_min_share=0",
        "mapping.mapper.segmentation.fingertip_radius_m=0",
        "sensor.rgbd.depth_noise=kinect",
        "sensor.rgbd.realsense.baseline_m=0",
        "sensor.rgbd.realsense.grazing_deg=95",
        "sensor.rgbd.backdrop_distance=0.2",
    ],
)
def test_bad_camera_values_are_one_line_config_errors(override: str) -> None:
    key = override.split("=")[0].rsplit(".", 1)[-1]
    with pytest.raises(ConfigError, match=key) as info:
        validate_config(compose_config([override]))
    assert "\n" not in str(info.value)
