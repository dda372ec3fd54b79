"""Per-press-kind accuracy: which images were centred, edge or feature presses, and how each did."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.perception.classifier.dataset import press_kinds
from neuralfeels_sem.perception.classifier.evaluate import per_press_kind


def test_press_kinds_come_from_the_manifest(tmp_path: Path) -> None:
    paths = [str(tmp_path / "index" / "wood" / f"{i:05d}.png") for i in range(3)]
    assert press_kinds(tmp_path, paths) is None  # no manifest: real data
    (tmp_path / "manifest.json").write_text(json.dumps({"total": 3}))
    assert press_kinds(tmp_path, paths) is None  # an older sim set without per-image kinds
    presses = {"index/wood/00000.png": "centre", "index/wood/00001.png": "feature+edge"}
    (tmp_path / "manifest.json").write_text(json.dumps({"presses": presses}))
    assert press_kinds(tmp_path, paths).tolist() == ["centre", "feature+edge", "unknown"]
    (tmp_path / "manifest.json").write_text("{not json")
    assert press_kinds(tmp_path, paths) is None


def test_per_press_kind_accuracy() -> None:
    kinds = np.array(["centre", "centre", "edge", "edge", "edge"])
    report = per_press_kind(np.array([0, 1, 2, 3, 0]), np.array([0, 1, 2, 0, 1]), kinds)
    assert report == {
        "centre": {"accuracy": 1.0, "count": 2},
        "edge": {"accuracy": pytest.approx(1 / 3), "count": 3},
    }
    with pytest.raises(ValueError, match="lengths differ"):
        per_press_kind(np.zeros(2), np.zeros(2), kinds)
