"""Material classifier inference speed: images/s for a batch of 4 DIGIT frames (one per finger).

Measured through `MaterialClassifier.predict_images` (resize + normalise + EfficientNet-B0),
at the paper's 224 px input and at the shipped checkpoint's input size, on the CPU (the
run's threads; ONNX Runtime, the default, and the traced torch model, `_torch`, side by
side) and on a CUDA GPU when one is visible. Also times the contact gate per frame.
Target: >= 30 images/s at batch 4, i.e. every finger at 7.5 Hz.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.perception.classifier import SHIPPED_CHECKPOINT, MaterialClassifier
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD
from neuralfeels_sem.perception.contact import ContactGate

CLASSES = list(DEFAULT_MATERIALS)
BATCH = 4


def _images_per_second(clf: MaterialClassifier, frames: np.ndarray, seconds: float = 8.0) -> float:
    for _ in range(3):  # warm-up (allocator, cuDNN autotune)
        clf.predict_images(frames)
    count, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        clf.predict_images(frames)
        count += len(frames)
    if clf._device is not None and clf._device.type == "cuda":
        torch.cuda.synchronize()
    return count / (time.perf_counter() - start)


def _variants(devices: list[str]) -> list[tuple[str, str, str]]:
    """(device, cpu_runtime, key suffix) of each measurement."""
    variants = [("cpu", "onnxruntime", "cpu"), ("cpu", "torch", "cpu_torch")]
    return variants + [(d, "torch", d) for d in devices if d != "cpu"]


def run() -> dict:
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (BATCH, 320, 240, 3), dtype=np.uint8)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    result: dict = {"batch": BATCH, "load_average_1min": round(os.getloadavg()[0], 1)}
    with tempfile.TemporaryDirectory() as tmp:
        paper = Path(tmp) / "b0_224.pt"
        save_checkpoint(
            paper, build_model(len(CLASSES)), CLASSES, 224, list(IMAGENET_MEAN), list(IMAGENET_STD)
        )
        checkpoints = {"224px": paper}
        if SHIPPED_CHECKPOINT.is_file():
            shipped = load_checkpoint(SHIPPED_CHECKPOINT)
            checkpoints[f"shipped_{shipped.input_size}px"] = SHIPPED_CHECKPOINT
            names = shipped.class_names
        for label, path in checkpoints.items():
            classes = names if label.startswith("shipped") else CLASSES
            for device, runtime, key in _variants(devices):
                clf = MaterialClassifier(
                    classes, checkpoint=str(path), device=device, cpu_runtime=runtime
                ).open()
                result[f"images_per_s_{label}_{key}"] = round(_images_per_second(clf, frames), 1)
    gate = ContactGate()
    background = frames[0].copy()
    start, n = time.perf_counter(), 0
    while time.perf_counter() - start < 2.0:
        gate.in_contact(frames[n % BATCH], background)
        n += 1
    result["contact_gate_ms_per_frame"] = round(1000 * (time.perf_counter() - start) / n, 2)
    result["cpu_threads"] = torch.get_num_threads()
    if torch.cuda.is_available():
        result["gpu"] = torch.cuda.get_device_name(0)
    return result
