"""Simulated rig throughput: physics steps, rig updates, DIGIT and camera renders, whole frames.

Target on a 2-core CPU: the whole rig (4 tactile + 1 RGB-D per frame) at >= 10 Hz.
"""

from __future__ import annotations

import time

import numpy as np

from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.sensors.sim import SimSensor

CLASSES = list(DEFAULT_MATERIALS)


def _rate(count: int, seconds: float) -> float:
    return round(count / seconds, 2)


def run() -> dict:
    obj = make_object("plushie", CLASSES)
    sensor = SimSensor(obj, class_names=CLASSES, duration_s=30.0, fps=10.0, seed=0)
    sensor.open()
    rig, scene = sensor.rig, sensor.rig.scene
    sensor.frame_at(0)  # GL contexts, caches

    start = time.perf_counter()
    scene.step(2000)
    steps_per_s = _rate(2000, time.perf_counter() - start)

    n = 30
    start = time.perf_counter()
    states = [rig.state_at(i / 10.0) for i in range(1, n + 1)]
    rig_hz = _rate(n, time.perf_counter() - start)

    start = time.perf_counter()
    for state in states:
        for finger in FINGERS:
            sensor.renderers[finger].render(state.world_T_object, state.world_T_sensor[finger])
    tactile_per_s = _rate(n * len(FINGERS), time.perf_counter() - start)

    start = time.perf_counter()
    for state in states:
        sensor.camera_renderer.render(state.world_T_object, occluders=scene.hand_meshes())
    camera_per_s = _rate(n, time.perf_counter() - start)

    start = time.perf_counter()
    for i in range(n + 1, 2 * n + 1):
        sensor.frame_at(i)
    full_hz = _rate(n, time.perf_counter() - start)
    touching = float(np.mean([sum(s.touching.values()) for s in states]))
    sensor.close()
    return {
        "object": "plushie",
        "sim_steps_per_s": steps_per_s,
        "rig_updates_per_s": rig_hz,  # policy + IK + press control
        "tactile_frames_per_s": tactile_per_s,  # single DIGIT renders
        "tactile_4_fingers_per_s": round(tactile_per_s / len(FINGERS), 2),
        "camera_frames_per_s": camera_per_s,
        "full_frames_per_s": full_hz,  # 4 tactile + 1 RGB-D + rig
        "mean_fingers_touching": round(touching, 2),
        "meets_10hz": full_hz >= 10.0,
    }
