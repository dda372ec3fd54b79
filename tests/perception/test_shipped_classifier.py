"""The shipped classifier (assets/classifier/) loads, is documented, and keeps its accuracy on fresh sim data."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.perception.classifier import SHIPPED_CHECKPOINT
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
from tests.helpers import compose_config, run_cli

ASSET_DIR = SHIPPED_CHECKPOINT.parent


def test_shipped_checkpoint_loads_with_its_provenance() -> None:
    ckpt = load_checkpoint(SHIPPED_CHECKPOINT)
    assert ckpt.class_names == DEFAULT_MATERIALS == list(compose_config().materials)
    assert SHIPPED_CHECKPOINT.stat().st_size < 12 * 2**20
    report = json.loads((ASSET_DIR / "report.json").read_text())
    manifest = json.loads((ASSET_DIR / "manifest.json").read_text())
    assert ckpt.meta["test_accuracy"] == pytest.approx(report["test_accuracy"])
    assert set(report["per_sensor"]) == {"index", "middle", "ring", "thumb"}
    assert manifest["classes"] == ckpt.class_names
    readme = (ASSET_DIR / "README.md").read_text()
    assert (
        "task=train_classifier" in readme and f"classifier.input_size={ckpt.input_size}" in readme
    )
    model = ckpt.build("cpu")
    assert model._fc.out_features == len(ckpt.class_names)


@pytest.mark.slow
def test_shipped_checkpoint_keeps_its_accuracy_on_fresh_sim_data(tmp_path: Path) -> None:
    """A new sim test set (another seed than the training data) through task=eval_classifier."""
    root = tmp_path / "fresh"
    # The same kinds of press as the simulated part of the shipped model's training data.
    trained_on = json.loads((ASSET_DIR / "manifest.json").read_text())["dataset"]
    collect = run_cli(
        [
            "task=collect_tactile",
            f"dataset.root={root}",
            "task.samples_per_class_per_sensor=5",
            f"task.edge_press_fraction={trained_on.get('edge_press_fraction', 0.0)}",
            f"task.feature_press_fraction={trained_on.get('feature_press_fraction', 0.0)}",
            "seed=777",
            f"hydra.run.dir={tmp_path / 'collect'}",
        ]
    )
    assert collect.returncode == 0, collect.stderr[-3000:]
    result = run_cli(
        ["task=eval_classifier", f"dataset.root={root}", f"hydra.run.dir={tmp_path / 'eval'}"]
    )
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads((tmp_path / "eval" / "report.json").read_text())
    # The shipped model's figure on a larger fresh collection of the same recipe.
    shipped = json.loads((ASSET_DIR / "held_out_fresh_mixed_781.json").read_text())
    assert report["test_count"] == 80 and set(report["per_sensor"]) == {
        "index",
        "middle",
        "ring",
        "thumb",
    }
    # 80 fresh images: allow three binomial standard deviations below the shipped test accuracy.
    p = shipped["test_accuracy"]
    assert report["test_accuracy"] >= p - 3 * math.sqrt(p * (1 - p) / 80), report
    assert report["test_accuracy"] > 0.4  # well above chance (0.25) in any case
