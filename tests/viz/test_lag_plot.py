"""bench.map_lag's picture: one panel per run, the four series against sensor time."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from neuralfeels_sem.viz.lag_plot import plot_map_lag


def _record(policy: str) -> dict:
    series = ((0.0, None, None), (1.0, 60.0, 70.0), (2.0, 90.0, 92.0), (3.0, 93.0, 93.0))
    rows = [
        {"time_s": t, "frame": int(10 * t), "field": 30 + 20 * t, "kept": k, "readings": r}
        for t, k, r in series
    ]
    for row in rows:
        row["placement"] = 95.0
    return {"object": "patchwork", "seed": 0, "policy": policy, "level": 90.0, "rows": rows}


def test_draws_a_panel_per_run_with_a_missing_value(tmp_path) -> None:
    path = plot_map_lag(
        [_record("scripted"), _record("active"), _record("active")], tmp_path / "lag.png", columns=2
    )
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape[0] > 300 and image.shape[1] > 500  # two rows of two panels
    assert image.std() > 10  # something was drawn


def test_no_record_is_a_value_error(tmp_path) -> None:
    with pytest.raises(ValueError, match="at least one record"):
        plot_map_lag([], tmp_path / "lag.png")
