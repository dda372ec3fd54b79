"""map_lag: the field's curve beside what the touches made so far allow, over sensor time."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.bench.map_lag import first_reached, kept_upto, lag_rows, summary_line
from neuralfeels_sem.eval.matching import MatchingEvaluator
from tests.eval.objects import two_material_sphere
from tests.eval.test_error_sources import FABRIC, PLASTIC, _press


@pytest.fixture(scope="module")
def sphere():
    obj = two_material_sphere()
    return obj, MatchingEvaluator(obj, num_samples=4000, seed=0)


def _history() -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """A plastic press at frame 0, an abstained fabric press at 10, a fabric press read as
    plastic at 12, and a fabric press read right at 25."""
    points = [_press(+1.0), _press(-1.0), _press(-1.0, x=0.3), _press(-1.0, x=-0.3)]
    labels = [np.full(32, PLASTIC), np.full(32, -1), np.full(32, PLASTIC), np.full(32, FABRIC)]
    return points, labels, np.array([0, 10, 12, 25])


def test_each_time_counts_only_the_touches_made_by_then(sphere) -> None:
    obj, matching = sphere
    curve = [[4, 0.5, 10.0], [9, 1.0, 20.0], [19, 2.0, 60.0], [29, 3.0, 95.0]]
    rows = lag_rows(obj, matching, _history(), curve, every_s=1.0)
    assert [r["time_s"] for r in rows] == [1.0, 2.0, 3.0]  # 0.5 s is not a whole second
    assert [r["field"] for r in rows] == [20.0, 60.0, 95.0]
    # 1 s: one plastic press, read right; placement alike (a constant map: half the classes).
    assert rows[0]["readings"] == pytest.approx(50.0)
    assert rows[0]["placement"] == pytest.approx(50.0)
    # 2 s: the fabric side is pressed (placement splits the sphere near its border) but
    # read only wrongly or not at all.
    assert rows[1]["readings"] == pytest.approx(50.0)
    assert rows[1]["placement"] > 95.0
    # 3 s: a right fabric reading takes back part of the fabric side from the misread one.
    assert 50.0 < rows[2]["readings"] < rows[2]["placement"]
    assert first_reached(rows, "placement", 90.0) == 2.0
    assert first_reached(rows, "readings", 60.0) == 3.0
    assert first_reached(rows, "readings", 90.0) is None
    assert first_reached(rows, "field", 99.0) is None


def test_a_time_before_any_touch_has_no_touch_maps(sphere) -> None:
    obj, matching = sphere
    points, labels, frames = _history()
    rows = lag_rows(obj, matching, (points, labels, frames + 100), [[9, 1.0, 5.0]], 1.0)
    assert rows == [
        {"time_s": 1.0, "frame": 9, "field": 5.0, "kept": None, "readings": None, "placement": None}
    ]


def test_bad_spacing_is_a_value_error(sphere) -> None:
    obj, matching = sphere
    with pytest.raises(ValueError, match="--every"):
        lag_rows(obj, matching, _history(), [[9, 1.0, 5.0]], every_s=0.0)


def test_summary_line_names_each_series() -> None:
    record = {
        "object": "patchwork",
        "seed": 1,
        "policy": "active",
        "level": 90.0,
        "first_reached_s": {"field": 10.5, "kept": 9.0, "readings": 8.0, "placement": None},
    }
    assert summary_line(record) == (
        "patchwork seed 1 active: first at 90 % mean-class: field 10.5 s, kept 9.0 s, "
        "readings 8.0 s, placement -"
    )


def test_nearest_scores_need_one_label_per_point(sphere) -> None:
    _, matching = sphere
    with pytest.raises(ValueError, match="one label per point"):
        matching.nearest_scores(np.zeros((3, 3)), np.zeros(2, dtype=int))
    with pytest.raises(ValueError, match="at least one point"):
        matching.nearest_scores(np.zeros((0, 3)), np.zeros(0, dtype=int))


def test_no_finished_run_is_a_one_line_error(tmp_path) -> None:
    from neuralfeels_sem.bench.map_lag import main

    with pytest.raises(SystemExit, match="no finished map run"):
        main([str(tmp_path)])


def test_an_uneven_curve_is_read_at_its_latest_point_before_each_step() -> None:
    from neuralfeels_sem.bench.map_lag import sampled

    curve = [[3, 0.3, 1.0], [8, 0.8, 2.0], [17, 1.7, 3.0], [22, 2.2, 4.0]]
    assert sampled(curve, 1.0) == [[8, 0.8, 2.0], [17, 1.7, 3.0], [22, 2.2, 4.0]]  # and the end
    assert sampled(curve, 0.5) == curve
    assert sampled([], 1.0) == []


def test_help_and_bad_spacing_on_the_command_line(capsys) -> None:
    from neuralfeels_sem.bench.map_lag import main

    with pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0 and "mean-class % to reach" in capsys.readouterr().out
    with pytest.raises(SystemExit) as done:
        main(["somewhere", "--every", "0"])
    assert done.value.code == 2 and "--every=0.0 must be > 0 seconds" in capsys.readouterr().err


def test_kept_follows_the_vote_as_it_stood_at_each_frame(sphere) -> None:
    """Each side read right by one lone press, then backed by a second press: the vote keeps
    a side's labels only from its second press on, while every reading counts at once."""
    import torch

    from neuralfeels_sem.mapping.label_vote import LabelVote
    from neuralfeels_sem.mapping.touch_memory import TouchBuffer

    obj, matching = sphere
    vote = LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=1,
                     press_gap=0, support_radius=0.04, steady_frames=0, press_reach=None)  # fmt: skip
    buffer = TouchBuffer(torch.device("cpu"), vote)
    presses = [(0, "index", +1.0, 0.0, PLASTIC), (3, "middle", -1.0, 0.0, FABRIC),
               (6, "ring", +1.0, 0.1, PLASTIC), (9, "thumb", -1.0, 0.1, FABRIC)]  # fmt: skip
    for frame, finger, side, x, label in presses:
        points = torch.tensor(_press(side, x), dtype=torch.float32)
        buffer.add(points, torch.tensor([0.0, side, 0.0]), label, 1.0, finger, frame)
    history = (
        [_press(side, x) for _, _, side, x, _ in presses],
        [np.full(32, label) for *_, label in presses],
        np.array([p[0] for p in presses]),
    )
    curve = [[0, 0.0, 1.0], [3, 0.3, 2.0], [6, 0.6, 3.0], [9, 0.9, 4.0]]
    rows = lag_rows(obj, matching, history, curve, 0.3, kept_upto(buffer))
    assert [r["kept"] for r in rows[:2]] == [None, None]  # lone presses: nothing kept yet
    assert rows[2]["kept"] == pytest.approx(50.0)  # plastic backed, fabric not yet
    assert rows[3]["kept"] > 95.0
    assert first_reached(rows, "readings", 90.0) == pytest.approx(0.3)
    assert first_reached(rows, "kept", 90.0) == pytest.approx(0.9)
    assert kept_upto(buffer)(-1)[0].shape == (0, 3)  # before any touch
