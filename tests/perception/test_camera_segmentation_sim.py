"""Camera segmentation on simulated frames (RealSense-like noise, lab scenery) against the GT mask."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.mapping.frame_points import PointExtractor
from neuralfeels_sem.perception.camera_segmentation import SegmentationConfig
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig
from neuralfeels_sem.sensors.sim import SimSensor
from tests.sim.shapes import CLASSES, two_material_sphere


@pytest.fixture(scope="module")
def segmented():
    sensor = SimSensor(
        two_material_sphere(),
        class_names=CLASSES,
        duration_s=0.4,
        fps=10.0,
        seed=0,
        rgbd={
            "depth_noise": "realsense",
            "table_height": 0.0,
            "backdrop_distance": 0.8,
            "mount": True,
        },
    )
    with sensor:
        extractor = PointExtractor(
            "segment", TactileDepth(TactileDepthConfig()), SegmentationConfig(), sensor.hand_model()
        )
        frames = list(sensor.frames())
        points = [extractor(frame, frame.world_T_object) for frame in frames]
    return frames, points, extractor


def test_mask_matches_the_ground_truth(segmented) -> None:
    frames, _, extractor = segmented
    summary = extractor.stats.summary()
    assert summary["camera_frames_segmented"] == len(frames) == 4
    assert summary["camera_frames_no_object"] == 0
    assert summary["mask_iou_mean"] >= 0.85


def test_scenery_is_in_view_but_not_in_the_points(segmented) -> None:
    frames, points, _ = segmented
    for frame, pts in zip(frames, points, strict=True):
        seen = frame.camera.depth > 0
        assert seen.mean() > 0.8  # table and backdrop fill the view
        # Object-frame camera points lie on the sphere (radius 4 cm, tests/sim/shapes.py).
        assert np.percentile(np.linalg.norm(pts["camera"], axis=1), 95) < 0.045
