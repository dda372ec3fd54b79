"""Camera segmentation without ground truth on simulated runs, and what the camera scene costs.

Per object (seed 0, the first 10 s of the default run at 10 fps, sensor.rgbd as configured by default
but with depth_noise=realsense): the segmentation's mean IoU against the simulator's object
mask (valid-depth pixels), its worst frame, frames with no object found, and ms per frame.
Then the RGB-D render rate of the bare camera (object and hand only, exact depth), with
the lab scenery, and with the scenery and RealSense-like noise.
Targets: mean IoU >= 0.9 on plushie and patched_toy.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from neuralfeels_sem.configs.sensor_sim import SimRgbdConfig
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.mapping.frame_points import fingertip_points
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.perception.camera_segmentation import CameraSegmenter, SegmentationConfig
from neuralfeels_sem.perception.segmentation_stats import SegmentationStats
from neuralfeels_sem.sensors.sim import SimSensor

CLASSES = list(DEFAULT_MATERIALS)
OBJECTS = ("plushie", "patched_toy")
BARE = {"table_height": None, "backdrop_distance": None, "mount": False, "depth_noise": "none"}


def _rgbd(**changes) -> dict:
    return dataclasses.asdict(dataclasses.replace(SimRgbdConfig(), **changes))


def _segment_run(name: str) -> dict:
    # The first 10 s of the default motion (100 frames): the figure stays comparable with
    # earlier bench.json files whatever the default run length.
    sensor = SimSensor(
        make_object(name, CLASSES),
        class_names=CLASSES,
        seed=0,
        duration_s=10.0,
        rgbd=_rgbd(depth_noise="realsense"),
    )
    stats, ious = SegmentationStats(), []
    with sensor:
        segmenter = CameraSegmenter(SegmentationConfig(), sensor.hand_model())
        for frame in sensor.frames():
            result = segmenter(frame.camera, frame.joint_positions, fingertip_points(frame))
            stats.add(result, frame.camera.depth, frame.camera.mask)
            ious.append(stats.last_iou)
        segmenter.close()
    summary = stats.summary()
    return {
        "frames": summary["camera_frames_segmented"],
        "mask_iou_mean": round(summary["mask_iou_mean"], 4),
        "mask_iou_min": round(float(np.min(ious)), 4),
        "frames_no_object": summary["camera_frames_no_object"],
        "segmentation_ms": round(summary["segmentation_ms_mean"], 1),
        "meets_iou_0_9": summary["mask_iou_mean"] >= 0.9,
    }


def _camera_rate(rgbd: dict, frames: int = 60) -> float:
    """Camera renders per second on plushie's first `frames` rig states."""
    sensor = SimSensor(make_object("plushie", CLASSES), class_names=CLASSES, seed=0, rgbd=rgbd)
    with sensor:
        states = [sensor.rig.state_at(i / 10.0) for i in range(frames)]
        hands = [sensor.rig.scene.hand_meshes() for _ in states]
        sensor.camera_renderer.render(states[0].world_T_object, hands[0])  # GL context
        start = time.perf_counter()
        for state, hand in zip(states, hands, strict=True):
            sensor.camera_renderer.render(state.world_T_object, occluders=hand)
        return round(frames / (time.perf_counter() - start), 1)


def run() -> dict:
    out: dict = {name: _segment_run(name) for name in OBJECTS}
    out["camera_frames_per_s"] = {
        "bare": _camera_rate(_rgbd(**BARE)),
        "lab_scenery": _camera_rate(
            _rgbd(**{**BARE, "table_height": 0.0, "backdrop_distance": 0.8, "mount": True})
        ),
        "lab_scenery_realsense": _camera_rate(_rgbd(depth_noise="realsense")),
    }
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
