"""Files of the run-output contract (docs/design.md) that are not pictures: metrics.json,
touches.csv, progression snapshots, and what a timing depends on. Every file is written
atomically."""

from __future__ import annotations

import csv
import json
import os
import platform
from pathlib import Path

import numpy as np

from neuralfeels_sem.utils.atomic import atomic_write, atomic_write_text


def machine_info(device) -> dict:
    """What a timing depends on: the machine, its load and the threads torch used."""
    import torch

    return {
        "cpu": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "device": str(device),
    }


def load_avg() -> list[float]:
    """The 1, 5 and 15 minute load averages now."""
    return [round(x, 2) for x in os.getloadavg()]


def write_metrics(metrics: dict, path: Path) -> None:
    atomic_write_text(path, json.dumps(metrics, indent=2, default=json_default))


def write_touches(
    touch_log: list[list], class_names: list[str], path: Path, partial: bool = False
) -> None:
    """One row per touch; a partial run (stopped by a signal) says so in a first `#` line."""
    with atomic_write(path, newline="") as f:
        if partial:
            f.write("# partial: the run was interrupted; resume it to complete this log\n")
        writer = csv.writer(f)
        writer.writerow(
            ["frame", "finger", "predicted", "ground_truth", "confidence", "top_class", "abstained"]
        )
        for frame, finger, predicted, gt, confidence, top, abstained in touch_log:
            writer.writerow(
                [
                    frame,
                    finger,
                    class_names[predicted] if predicted >= 0 else "none",
                    class_names[gt] if gt >= 0 else "unknown",
                    f"{confidence:.3f}",
                    class_names[top] if top >= 0 else "none",
                    abstained,
                ]
            )


def write_snapshot(path: Path, time_s: float, maps: dict) -> None:
    """One progression snapshot (the image-form maps of the field at `time_s`)."""
    with atomic_write(path, "wb") as f:
        np.savez_compressed(
            f,
            time_s=time_s,
            gt=maps["gt"],
            pred=maps["pred"],
            diff=maps["diff"],
            shade=maps["shade"],
            entropy=maps["entropy"],
            matching_pct_image=maps["matching_pct_image"],
        )


def json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
