"""experiment=classifier: collect -> train -> held-out evaluation in one sweep job, then the aggregate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.helpers import run_cli


@pytest.mark.slow
def test_classifier_experiment_pipeline_at_toy_size(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    result = run_cli(
        [
            "experiment=classifier",
            "task.samples_per_class_per_sensor=3",
            "task.heldout_per_class_per_sensor=2",
            "task.input_size=32",
            "task.max_epochs=1",
            "task.patience=1",
            f"hydra.sweep.dir={sweep}",
        ],
        timeout=900,
    )
    assert result.returncode == 0, result.stderr[-4000:]
    job = sweep / "0"
    for path in (
        "train/classifier.pt",
        "train/confusion.png",
        "train/per_sensor.png",
        "heldout_eval/report.json",
    ):
        assert (job / path).is_file(), path
    manifest = json.loads((job / "data" / "train" / "manifest.json").read_text())
    assert all(n == 3 for counts in manifest["counts"].values() for n in counts.values())
    report = json.loads((job / "report.json").read_text())
    assert 0.0 <= report["test_accuracy"] <= 1.0
    assert set(report["heldout_per_sensor"]) == {"index", "middle", "ring", "thumb"}
    held = json.loads((job / "heldout_eval" / "report.json").read_text())
    assert held["data"]["images"] == 2 * 4 * 4
    summary = json.loads((sweep / "summary.json").read_text())
    assert summary["failed"] == [] and "heldout_accuracy" in summary["groups"][0]["metrics"]
