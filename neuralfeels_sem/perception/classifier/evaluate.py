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


def predict_probs_in_batches(
    predict, images: np.ndarray, batch_size: int, desc: str = "classifying"
) -> np.ndarray:
    """(N, C) probabilities for (N, S, S, 3) images, `predict` mapping a batch to (B, C)."""
    out = []
    for start in tqdm(range(0, len(images), batch_size), desc=desc, unit="batch", leave=False):
        out.append(np.asarray(predict(images[start : start + batch_size]), dtype=np.float32))
    return np.concatenate(out) if out else np.zeros((0, 0), dtype=np.float32)


def predict_in_batches(
    predict, images: np.ndarray, batch_size: int, desc: str = "classifying"
) -> np.ndarray:
    """Class indices for (N, S, S, 3) images, `predict` mapping a batch to (B, C) probabilities."""
    probs = predict_probs_in_batches(predict, images, batch_size, desc)
    return probs.argmax(1) if len(probs) else np.zeros(0, dtype=np.int64)


def gated_report(
    y_true: np.ndarray,
    probs: np.ndarray,
    edge_shares: np.ndarray,
    min_confidence: float,
    max_edge_share: float,
) -> dict:
    """Accuracy on the touches the mapper would label, and how many it would leave out.

    A touch is labelled when its top probability reaches `min_confidence` and at most
    `max_edge_share` of its contact lies in the sensor's border band (1.0 = no edge check).
    """
    if not len(y_true) == len(probs) == len(edge_shares):
        raise ValueError(
            f"lengths differ: {len(y_true)} labels, {len(probs)} predictions, "
            f"{len(edge_shares)} edge shares"
        )
    confident = probs.max(1) >= min_confidence
    inside = (edge_shares <= max_edge_share) | (max_edge_share >= 1.0)
    kept = confident & inside
    correct = probs.argmax(1) == y_true
    return {
        "min_confidence": float(min_confidence),
        "max_edge_share": float(max_edge_share),
        "kept_share": float(kept.mean()) if len(kept) else 0.0,
        "kept_count": int(kept.sum()),
        "accuracy_kept": float(correct[kept].mean()) if kept.any() else None,
        "left_out_low_confidence": int((~confident).sum()),
        "left_out_edge": int((confident & ~inside).sum()),
    }


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


# Bins of the bend radius 1 / curvature (mm) at a press: rims and edges; the tight
# training primitives (18-25 mm); gentle bends (35-45 mm); flat.
CURVATURE_BINS_MM = ((0.0, 12.0), (12.0, 30.0), (30.0, 80.0), (80.0, float("inf")))


def _bin_label(low: float, high: float) -> str:
    if low == 0:
        return f"R < {high:g} mm"
    return f"R {low:g}-{high:g} mm" if np.isfinite(high) else f"R >= {low:g} mm"


def curvature_bin_labels() -> list[str]:
    """Every bin's label, tightest bend first (the order reports are read in)."""
    return [_bin_label(low, high) for low, high in CURVATURE_BINS_MM]


def curvature_bin(curvature_per_m: float) -> str:
    """The bin label of a curvature: its bend radius range in millimetres ("unknown": NaN)."""
    if not np.isfinite(curvature_per_m):
        return "unknown"
    radius_mm = 1e3 / curvature_per_m if curvature_per_m > 0 else float("inf")
    low, high = next(b for b in CURVATURE_BINS_MM if radius_mm < b[1] or np.isinf(b[1]))
    return _bin_label(low, high)


def per_press_kind(y_true: np.ndarray, y_pred: np.ndarray, kinds: np.ndarray) -> dict:
    """{kind: {"accuracy", "count"}}: accuracy per kind of press (centre, edge, feature, ...),
    or per any other label of each image (the curvature bin at the press).

    Centred presses are the paper's protocol (a sample pressed onto the gel); edge and
    feature presses are the rig's harder imprints.
    """
    if not len(y_true) == len(y_pred) == len(kinds):
        raise ValueError(
            f"lengths differ: {len(y_true)} labels, {len(y_pred)} predictions, {len(kinds)} kinds"
        )
    out = {}
    for kind in sorted(set(kinds.tolist())):
        sel = kinds == kind
        out[kind] = {
            "accuracy": float((y_true[sel] == y_pred[sel]).mean()),
            "count": int(sel.sum()),
        }
    return out
