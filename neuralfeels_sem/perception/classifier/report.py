"""Accuracy report of a classifier on a labelled set, and the paper's figure-3 plots.

report.json keys: `test_accuracy`, `val_accuracy`, `per_sensor` ({sensor: accuracy}),
`confusion` (rows = true class, columns = predicted, counts, in `class_names` order),
plus `class_names`, `per_class` and counts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def confusion_matrix(y_true: np.ndarray, y_pred: np.ndarray, num_classes: int) -> np.ndarray:
    if y_true.shape != y_pred.shape:
        raise ValueError(f"y_true {y_true.shape} and y_pred {y_pred.shape} differ")
    cm = np.zeros((num_classes, num_classes), dtype=np.int64)
    np.add.at(cm, (y_true, y_pred), 1)
    return cm


def accuracy_report(
    y_true: np.ndarray, y_pred: np.ndarray, sensors: np.ndarray, class_names: list[str]
) -> dict:
    """Overall, per-sensor and per-class accuracy plus the confusion matrix (plain types)."""
    if len(y_true) == 0:
        raise ValueError("cannot report accuracy on an empty set")
    correct = y_true == y_pred
    cm = confusion_matrix(y_true, y_pred, len(class_names))
    per_class = {
        c: float(correct[y_true == i].mean())
        for i, c in enumerate(class_names)
        if (y_true == i).any()
    }
    per_sensor = {s: float(correct[sensors == s].mean()) for s in sorted(set(sensors.tolist()))}
    return {
        "accuracy": float(correct.mean()),
        "count": int(len(y_true)),
        "per_sensor": per_sensor,
        "per_class": per_class,
        "confusion": cm.tolist(),
        "class_names": list(class_names),
    }


def plot_confusion(
    cm: np.ndarray, class_names: list[str], path: str | Path, title: str = ""
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cm = np.asarray(cm, dtype=float)
    rows = cm.sum(axis=1, keepdims=True)
    norm = np.divide(cm, rows, out=np.zeros_like(cm), where=rows > 0)
    fig, ax = plt.subplots(figsize=(1.2 * len(class_names) + 2, 1.1 * len(class_names) + 1.5))
    ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    for i in range(len(class_names)):
        for j in range(len(class_names)):
            ax.text(
                j,
                i,
                f"{norm[i, j]:.2f}\n({int(cm[i, j])})",
                ha="center",
                va="center",
                color="white" if norm[i, j] > 0.5 else "black",
                fontsize=8,
            )
    ax.set_xticks(range(len(class_names)), class_names, rotation=30)
    ax.set_yticks(range(len(class_names)), class_names)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title or "confusion (row-normalised)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_per_sensor(per_sensor: dict[str, float], path: str | Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(per_sensor)
    values = [100 * per_sensor[n] for n in names]
    fig, ax = plt.subplots(figsize=(1.3 * len(names) + 2, 3.5))
    bars = ax.bar(names, values, color="tab:blue")
    for bar, v in zip(bars, values):
        ax.text(bar.get_x() + bar.get_width() / 2, v + 0.5, f"{v:.1f}", ha="center", fontsize=9)
    ax.set_ylim(0, 105)
    ax.set_ylabel("accuracy (%)")
    ax.set_title(title or "accuracy per sensor")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
