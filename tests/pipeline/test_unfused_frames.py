"""A frame whose pose the pose source does not trust (not tracked) is not fused into the
map, while the field goes on training on what it has."""

from __future__ import annotations

from hydra.utils import instantiate

import neuralfeels_sem.tasks.map as map_task
from neuralfeels_sem.mapping.pose_source import PoseSource
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.map import map_object
from tests.helpers import compose_config
from tests.pipeline.test_observers import SMALL


class EveryOtherFrame(PoseSource):
    """The frame's own pose, trusted on even frames only."""

    def estimate(self, frame, mapper):
        self.fuse = frame.index % 2 == 0
        return super().estimate(frame, mapper)


class Counter:
    def __init__(self) -> None:
        self.seen: list[tuple[int, int, int]] = []  # frame, frames fused, optimiser steps

    def on_frame(self, frame, labels, world_T_object, mapper) -> None:
        self.seen.append((frame.index, mapper.log.frames_seen, mapper.log.steps))

    def on_scores(self, frame_index, scores, mapper) -> None:
        pass

    def close(self) -> None:
        pass


def test_untrusted_frames_train_but_are_not_fused(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(map_task, "build_pose_source", lambda *a, **k: EveryOtherFrame())
    cfg = compose_config(SMALL)
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, list(cfg.materials))
    counter = Counter()
    sensor.open()
    try:
        map_object(cfg, obj, sensor, tmp_path, observers=[counter])
    finally:
        sensor.close()
    fused = [n for _, n, _ in counter.seen]
    assert fused == [k // 2 + 1 for k, _, _ in counter.seen]  # odd frames add nothing
    steps = [s for _, _, s in counter.seen]
    assert all(b > a for a, b in zip(steps, steps[1:]))  # but every frame trains
