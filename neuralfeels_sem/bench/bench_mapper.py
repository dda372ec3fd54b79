"""Online mapper speed at the CPU default config: optimiser steps/s, add_frame frames/s, and
the realtime factor of the default run.

The field, optimiser and mapper use the config dataclass defaults, i.e. the command line's
(SemanticFieldConfig, OptimizerConfig, MapperConfig: 2^16 sparse hash table, FieldAdam, 288
camera + 96 tactile rays x 10 samples + up to 512 space-prior + 256 material points per
step; warm-up off). Data: the analytic sphere scene
(mapping/sphere_scene.py), one 96x72 camera view and four DIGIT touches per frame.
`steps_per_s` is measured with the thread count a run's `threads=auto` picks
(utils/device.py), `steps_per_s_by_threads` with 1 and 2 threads side by side (the load
average beside them: on a shared machine the ratio is the figure to read).
`default_run` is the default run itself (`python run.py`: sim, plushie, realistic
perception, its whole sensor time) in a child process: its realtime factor (sensor time /
the loop's wall time) against REALTIME_TARGET, and its mean-class matching beside the
majority map, so a faster loop that maps worse shows here too. The run is repeated
DEFAULT_RUN_REPEATS times one after another: on a shared machine the same run's CPU time
varies by a tenth between repeats, so one run's factor says little. The median run is
reported, with every run's factor (`realtime_factor_runs`) and the lowest and highest;
the maps of the repeats are identical (offline pace). With a CUDA GPU,
`default_run_cuda_log2_24` is the same run on the GPU at the paper's 2^24 table, and
`default_run_cuda_log2_24_sim_inline` that run again right after it with the simulator in
the mapping process (`mapping.acquire_process=false`).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch
from hydra.utils import instantiate

from neuralfeels_sem.fields.optim import OptimizerConfig
from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.sphere_scene import sphere_frames
from neuralfeels_sem.utils.device import resolve_device, resolve_threads
from neuralfeels_sem.utils.paths import REPO_DIR
from neuralfeels_sem.viz.run_report import busy_share, stage_shares

TIMED_STEPS = 20
DEFAULT_RUN_TIMEOUT_S = 900
REALTIME_TARGET = 0.5  # sensor time / loop time of the default run on a 2-core CPU
DEFAULT_RUN_REPEATS = 3  # CPU default runs, one after another; the median is reported
PAPER_LOG2_TABLE = 24


def default_mapper(num_classes: int = 4, **changes) -> OnlineMapper:
    """An OnlineMapper built from the config defaults (the command line's), plus `changes`."""
    field = SemanticField(SemanticFieldConfig(num_classes=num_classes), bound=0.1)
    factory = instantiate(OptimizerConfig())
    config = MapperConfig(num_classes=num_classes, **changes)
    return OnlineMapper(config, field, factory, resolve_device("cpu"))


def _time_steps(mapper: OnlineMapper, steps: int) -> tuple[float, float, int]:
    """(wall s, CPU s of all threads) per step over `steps` steps, and points per step."""
    start, cpu_start = time.perf_counter(), time.process_time()
    losses = mapper.optimize(steps)
    return (
        (time.perf_counter() - start) / steps,
        (time.process_time() - cpu_start) / steps,
        int(losses["points"]),
    )


def _steps_by_threads(mapper: OnlineMapper) -> dict:
    """Steps/s with 1 and 2 torch threads, alternated (1, 2, 1, 2) so load drifts hit both."""
    before = torch.get_num_threads()
    timings: dict[int, list[tuple[float, float]]] = {1: [], 2: []}
    try:
        for threads in (1, 2, 1, 2):
            torch.set_num_threads(threads)
            wall, cpu, _ = _time_steps(mapper, TIMED_STEPS // 2)
            timings[threads].append((wall, cpu))
    finally:
        torch.set_num_threads(before)
    out = {}
    for threads, pairs in timings.items():
        wall = sum(w for w, _ in pairs) / len(pairs)
        cpu = sum(c for _, c in pairs) / len(pairs)
        out[str(threads)] = {
            "steps_per_s": round(1.0 / wall, 2),
            "step_cpu_ms": round(1000 * cpu, 1),
        }
    return out


def _default_run(*overrides: str) -> dict:
    """Realtime factor and matching of the default run (a child process), with `overrides`."""
    with tempfile.TemporaryDirectory(prefix="bench_map_") as out:
        command = [sys.executable, "run.py", "viz.plots=false", f"hydra.run.dir={out}", *overrides]
        start = time.perf_counter()
        try:
            done = subprocess.run(
                command,
                cwd=REPO_DIR,
                capture_output=True,
                text=True,
                timeout=DEFAULT_RUN_TIMEOUT_S,
            )
        except subprocess.TimeoutExpired:
            # A loaded machine: keep the step figures, say what happened to this one.
            return {
                "error": f"no result within {DEFAULT_RUN_TIMEOUT_S} s "
                f"(load average {os.getloadavg()[0]:.1f})"
            }
        process_s = time.perf_counter() - start
        metrics_path = Path(out) / "metrics.json"
        if done.returncode != 0 or not metrics_path.exists():
            tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
            return {"error": f"exit {done.returncode}: {tail[0]}"}
        metrics = json.loads(metrics_path.read_text())
    return {
        "sensor_s": metrics["sensor_time_s"],
        "realtime_factor": round(metrics["realtime_factor"], 3),
        "meets_realtime_target": metrics["realtime_factor"] >= REALTIME_TARGET,
        "loop_wall_s": round(metrics["wall_s"], 1),
        # Shares of the loop each thread was busy: the one near 1 bounds the factor.
        "producer_busy": _busy(metrics, "producer_cpu_s"),
        "mapper_busy": _busy(metrics, "mapper_cpu_s"),
        "producer_stage_busy": _stage_busy(metrics),
        "process_wall_s": round(process_s, 1),
        "optimizer_steps": metrics["trained_on"]["optimizer_steps"],
        "matching_mean_class_pct": metrics["matching_mean_class_pct"],
        "baseline_majority_mean_class_pct": metrics["baseline_majority"].get(
            "matching_mean_class_pct"
        ),
        "threads": metrics.get("machine", {}).get("torch_threads"),
        "load_avg_1min_at_end": (metrics.get("load_avg") or [None])[0],
    }


def _busy(metrics: dict, key: str) -> float | None:
    share = busy_share(metrics, key)
    return None if share is None else round(share, 3)


def _stage_busy(metrics: dict) -> dict[str, float]:
    """The producer's stages as shares of the loop: which one to speed up where the
    producer bounds it."""
    return {stage: round(share, 3) for stage, share in stage_shares(metrics).items()}


def _repeated_default_run(repeats: int) -> dict:
    """The default run `repeats` times: the median run's figures (by realtime factor), every
    run's factor and the lowest and highest; an error of any run is reported as such."""
    runs = [_default_run() for _ in range(repeats)]
    failed = [r for r in runs if "error" in r]
    if failed:
        return failed[0]
    factors = [r["realtime_factor"] for r in runs]
    median = sorted(runs, key=lambda r: r["realtime_factor"])[len(runs) // 2]
    return {
        **median,
        "realtime_factor_runs": factors,
        "realtime_factor_min": min(factors),
        "realtime_factor_max": max(factors),
    }


def run() -> dict:
    torch.manual_seed(0)
    threads_before = torch.get_num_threads()
    torch.set_num_threads(resolve_threads("auto"))  # what a run uses by default
    frames = sphere_frames(12, touches_per_frame=4)
    mapper = default_mapper(warmup_steps=0)
    for frame, labels in frames[:4]:
        mapper.add_frame(frame, labels)  # fills the window; also warms up the allocator

    step_s, step_cpu_s, points = _time_steps(mapper, TIMED_STEPS)
    by_threads = _steps_by_threads(mapper)

    start = time.perf_counter()
    for frame, labels in frames[4:]:
        mapper.add_frame(frame, labels)
    frame_s = (time.perf_counter() - start) / len(frames[4:])

    start = time.perf_counter()
    for frame, _ in frames[4:]:
        mapper.frame_points(frame, frame.world_T_object)
    ingest_s = (time.perf_counter() - start) / len(frames[4:])
    result = {
        "points_per_step": points,
        "steps_per_s": round(1.0 / step_s, 2),
        "step_ms": round(1000 * step_s, 1),
        # CPU seconds (all threads) per step: comparable across runs on a shared, loaded machine.
        "step_cpu_ms": round(1000 * step_cpu_s, 1),
        "steps_per_s_by_threads": by_threads,
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "steps_per_frame": mapper.config.steps_per_frame,
        "add_frame_per_s": round(1.0 / frame_s, 2),
        "frame_points_ms": round(1000 * ingest_s, 1),
        "threads": torch.get_num_threads(),
    }
    torch.set_num_threads(threads_before)
    result["default_run"] = _repeated_default_run(DEFAULT_RUN_REPEATS)
    if torch.cuda.is_available():
        # The GPU target: the default run at the paper's table size (2^24 rows per level).
        paper = ("device=cuda", f"model.encoding.log2_table_size={PAPER_LOG2_TABLE}")
        result["default_run_cuda_log2_24"] = _default_run(*paper)
        # Right after it on the same machine: the simulator in the mapping process (its
        # own process is the default; docs/field_and_mapper.md#on-a-gpu).
        result["default_run_cuda_log2_24_sim_inline"] = _default_run(
            *paper, "mapping.acquire_process=false"
        )
    result["load_avg_1min_end"] = round(os.getloadavg()[0], 2)
    return result
