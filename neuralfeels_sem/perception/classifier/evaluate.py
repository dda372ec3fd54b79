"""Score a classifier on a loaded labelled set and write report.json with its figures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from neuralfeels_sem.perception.classifier.report import (
    accuracy_report,
    plot_confusion,
    plot_per_sensor,
)


def predict_in_batches(
    predict, images: np.ndarray, batch_size: int, desc: str = "classifying"
) -> np.ndarray:
    """Class indices for (N, S, S, 3) images, `predict` mapping a batch to (B, C) probabilities."""
    out = []
    for start in tqdm(range(0, len(images), batch_size), desc=desc, unit="batch", leave=False):
        out.append(predict(images[start : start + batch_size]).argmax(1))
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def write_report(report: dict, out_dir: Path, title: str) -> Path:
    """report.json plus confusion.png and per_sensor.png (the paper's figure 3) in out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "report.json"
    path.write_text(json.dumps(report, indent=2))
    plot_confusion(
        np.asarray(report["confusion"]),
        report["class_names"],
        out_dir / "confusion.png",
        title=f"{title}: accuracy {100 * report['test_accuracy']:.2f}%",
    )
    plot_per_sensor(
        report["per_sensor"], out_dir / "per_sensor.png", title=f"{title}: accuracy per sensor"
    )
    return path


def test_report(
    y_true: np.ndarray, y_pred: np.ndarray, sensors: np.ndarray, class_names: list[str]
) -> dict:
    """The report.json core: test accuracy, per-sensor accuracy and confusion of the test set."""
    core = accuracy_report(y_true, y_pred, sensors, class_names)
    return {
        "test_accuracy": core["accuracy"],
        "test_count": core["count"],
        "per_sensor": core["per_sensor"],
        "per_class": core["per_class"],
        "confusion": core["confusion"],
        "class_names": core["class_names"],
    }
