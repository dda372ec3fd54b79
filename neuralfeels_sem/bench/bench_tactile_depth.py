"""Tactile depth network inference speed: images/s for a batch of 4 DIGIT frames (one per
finger), through `DepthNetPredictor.predict` (downsampling, the network, upsampling to
320 x 240, thresholding), on the CPU with 1 and 2 threads, through ONNX Runtime (the
default) and torch (`torch_` keys). Uses the shipped checkpoint
(a fresh network of the same size when it is absent). Target: >= 100 images/s at batch 4.
The 1-minute load average is recorded beside the figures: on a shared machine, threads
that wait for a busy core cost more than they give.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from neuralfeels_sem.perception.tactile_depth_net import SHIPPED_CHECKPOINT, DepthNetPredictor
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import save_checkpoint
from neuralfeels_sem.perception.tactile_depth_net.model import build_model

BATCH = 4
FALLBACK_WIDTH, FALLBACK_SIZE = 16, (160, 120)  # the task's defaults


def _images_per_second(predictor: DepthNetPredictor, frames: np.ndarray, seconds: float) -> float:
    backgrounds = frames[::-1].copy()
    for _ in range(3):  # warm-up (allocator, oneDNN primitive cache)
        predictor.predict(frames, backgrounds)
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        predictor.predict(frames, backgrounds)
        count += len(frames)
    return count / (time.perf_counter() - start)


def run(seconds: float = 5.0) -> dict:
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (BATCH, 320, 240, 3), dtype=np.uint8)
    threads = torch.get_num_threads()
    result: dict = {"batch": BATCH, "shipped": SHIPPED_CHECKPOINT.is_file()}
    with tempfile.TemporaryDirectory() as tmp:
        path = SHIPPED_CHECKPOINT
        if not path.is_file():
            path = save_checkpoint(Path(tmp) / "d.pt", build_model(FALLBACK_WIDTH), FALLBACK_SIZE)
        for runtime, suffix in (("onnxruntime", ""), ("torch", "torch_")):
            for n in (1, 2):
                torch.set_num_threads(n)  # before loading: an ONNX session keeps its count
                predictor = DepthNetPredictor(path, cpu_runtime=runtime)
                predictor.load()
                result["input_size"] = list(predictor.input_size)
                result[f"load_average_1min_{suffix}{n}thread"] = round(os.getloadavg()[0], 2)
                rate = _images_per_second(predictor, frames, seconds)
                result[f"images_per_s_cpu_{suffix}{n}thread"] = round(rate, 1)
    torch.set_num_threads(threads)
    return result
