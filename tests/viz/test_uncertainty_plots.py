"""uncertainty_map.png: written from a snapshot with entropy; a snapshot without it is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.viz.run_report import load_snapshots
from neuralfeels_sem.viz.uncertainty_plots import plot_uncertainty_map
from tests.viz.images import assert_png
from tests.viz.test_plots import CLASSES, synthetic_maps


def maps_with_entropy() -> dict:
    """The synthetic disc, unsure (0.9) where the prediction is wrong and sure (0.1) elsewhere."""
    maps = synthetic_maps()
    entropy = np.where(maps["diff"], 0.9, 0.1).astype(np.float32)
    entropy[maps["gt"] == -2] = np.nan
    maps["entropy"] = entropy
    return maps


def test_uncertainty_map_is_a_picture_of_every_view(tmp_path: Path) -> None:
    path = plot_uncertainty_map(
        maps_with_entropy(), CLASSES, tmp_path / "uncertainty_map.png", title="AUROC 1.00"
    )
    assert_png(path, min_width=400, min_height=400)


def test_a_snapshot_without_entropy_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="entropy"):
        plot_uncertainty_map(synthetic_maps(), CLASSES, tmp_path / "u.png")


def test_snapshots_load_with_and_without_entropy(tmp_path: Path) -> None:
    """Snapshots from before uncertainty was recorded still load (a resumed older run)."""
    maps = maps_with_entropy()
    common = {k: maps[k] for k in ("gt", "pred", "diff", "shade")}
    np.savez(tmp_path / "000000.npz", time_s=0.0, matching_pct_image=50.0, **common)
    np.savez(
        tmp_path / "000004.npz",
        time_s=0.8,
        matching_pct_image=60.0,
        entropy=maps["entropy"],
        **common,
    )
    (old, old_maps), (new, new_maps) = load_snapshots(tmp_path)
    assert "entropy" not in old_maps and old == 0.0
    np.testing.assert_array_equal(new_maps["entropy"], maps["entropy"])
