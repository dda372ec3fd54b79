"""Online mapper speed at the CPU default config: optimiser steps/s and add_frame frames/s.

The field, optimiser and mapper use the config dataclass defaults, i.e. the command line's
(SemanticFieldConfig, OptimizerConfig, MapperConfig: 2^19 sparse hash table, FieldAdam, 288
camera + 96 tactile rays x 10 samples + up to 512 space-prior + 256 material points per
step; warm-up off). Data: the analytic sphere scene
(mapping/sphere_scene.py), one 96x72 camera view and four DIGIT touches per frame.
"""

from __future__ import annotations

import os
import time

import torch
from hydra.utils import instantiate

from neuralfeels_sem.fields.optim import OptimizerConfig
from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.sphere_scene import sphere_frames
from neuralfeels_sem.utils.device import resolve_device


def default_mapper(num_classes: int = 4, **changes) -> OnlineMapper:
    """An OnlineMapper built from the config defaults (the command line's), plus `changes`."""
    field = SemanticField(SemanticFieldConfig(num_classes=num_classes), bound=0.1)
    factory = instantiate(OptimizerConfig())
    config = MapperConfig(num_classes=num_classes, **changes)
    return OnlineMapper(config, field, factory, resolve_device("cpu"))


def run() -> dict:
    torch.manual_seed(0)
    frames = sphere_frames(12, touches_per_frame=4)
    mapper = default_mapper(warmup_steps=0)
    for frame, labels in frames[:4]:
        mapper.add_frame(frame, labels)  # fills the window; also warms up the allocator

    steps = 20
    start, cpu_start = time.perf_counter(), time.process_time()
    losses = mapper.optimize(steps)
    step_s = (time.perf_counter() - start) / steps
    # CPU seconds (all threads) per step: comparable across runs on a shared, loaded machine.
    step_cpu_s = (time.process_time() - cpu_start) / steps

    start = time.perf_counter()
    for frame, labels in frames[4:]:
        mapper.add_frame(frame, labels)
    frame_s = (time.perf_counter() - start) / len(frames[4:])

    start = time.perf_counter()
    for frame, _ in frames[4:]:
        mapper.frame_points(frame, frame.world_T_object)
    ingest_s = (time.perf_counter() - start) / len(frames[4:])
    return {
        "points_per_step": int(losses["points"]),
        "steps_per_s": round(1.0 / step_s, 2),
        "step_ms": round(1000 * step_s, 1),
        "step_cpu_ms": round(1000 * step_cpu_s, 1),
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "steps_per_frame": mapper.config.steps_per_frame,
        "add_frame_per_s": round(1.0 / frame_s, 2),
        "frame_points_ms": round(1000 * ingest_s, 1),
        "threads": torch.get_num_threads(),
    }
