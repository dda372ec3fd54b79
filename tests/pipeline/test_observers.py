"""Observers see every mapped frame and scoring pass, and do not change the run; the
session's settings reach its checkpoints."""

from __future__ import annotations

import numpy as np
from hydra.utils import instantiate

from neuralfeels_sem.pipeline.observers import FrameObserver
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.map import map_object
from tests.helpers import TOY_MAPPING, compose_config

SMALL = [
    "object=patched_toy",
    "sensor.rgbd.width=96",
    "sensor.rgbd.height=72",
    "sensor.duration_s=0.6",
    "sensor.fps=5",
    *TOY_MAPPING,
]


class Recorder:
    def __init__(self) -> None:
        self.frames: list[int] = []
        self.scored: list[int] = []
        self.labels: list[dict] = []
        self.closed = 0

    def on_frame(self, frame, labels, world_T_object, mapper) -> None:
        assert world_T_object.shape == (4, 4)
        self.frames.append(frame.index)
        self.labels.append(labels)

    def on_scores(self, frame_index, scores, mapper) -> None:
        self.scored.append(frame_index)

    def close(self) -> None:
        self.closed += 1


def test_an_observer_sees_every_frame_and_scoring_pass(tmp_path, monkeypatch) -> None:
    import neuralfeels_sem.pipeline.mapping_session as session_module

    storages = []
    take = session_module.take_checkpoint

    def recording_take(*args, storage="auto", **kwargs):
        storages.append(storage)
        return take(*args, storage=storage, **kwargs)

    monkeypatch.setattr(session_module, "take_checkpoint", recording_take)
    cfg = compose_config([*SMALL, "mapping.checkpoint_storage=exact"])
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, list(cfg.materials))
    recorder = Recorder()
    assert isinstance(recorder, FrameObserver)
    sensor.open()
    try:
        metrics = map_object(cfg, obj, sensor, tmp_path, observers=[recorder])
    finally:
        sensor.close()
    assert recorder.frames == list(range(metrics["frames"]))
    assert recorder.scored == [i for i in recorder.frames if i % 3 == 0 or i == recorder.frames[-1]]
    assert recorder.closed == 1
    assert all(set(labels) <= {"index", "middle", "ring", "thumb"} for labels in recorder.labels)
    assert np.isfinite(metrics["matching_mean_class_pct"])
    assert storages and set(storages) == {"exact"}  # mapping.checkpoint_storage reaches the file
