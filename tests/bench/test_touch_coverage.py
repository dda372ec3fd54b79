"""bench.touch_coverage: which materials the rig's fingers touch, per policy (rig only)."""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import pytest

from neuralfeels_sem.bench import touch_coverage
from neuralfeels_sem.bench.touch_coverage import coverage, run, touched_materials
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object

FRAMES = 12  # 1.2 s: every finger has landed once


def test_coverage_counts_materials_touched_often_enough() -> None:
    touched = Counter({"plastic": 3, "metal": 1, "ignore": 9})
    assert coverage(touched, ["plastic", "metal", "wood"], 1) == pytest.approx(2 / 3)
    assert coverage(touched, ["plastic", "metal", "wood"], 2) == pytest.approx(1 / 3)
    assert coverage(touched, ["wood"], 1) == 0.0


@pytest.mark.parametrize("policy", ["scripted", "active"])
def test_touched_materials_are_the_touching_fingers_materials(policy: str) -> None:
    obj = make_object("patched_toy", DEFAULT_MATERIALS)
    touched, rig = touched_materials(obj, policy, frames=FRAMES)
    assert sum(touched.values()) > 0, "the fingers touch patched_toy within 1.2 s"
    assert set(touched) <= {"plastic", "fabric", "ignore"}  # patched_toy's materials
    assert (rig.planner is None) == (policy == "scripted")
    again, _ = touched_materials(obj, policy, frames=FRAMES)
    assert again == touched  # same seed, same touches


def test_unknown_policy_is_refused() -> None:
    with pytest.raises(ValueError, match="policy='random'"):
        touched_materials(make_object("patched_toy", DEFAULT_MATERIALS), "random", frames=1)


def test_run_reports_each_object_and_policy(tmp_path: Path, monkeypatch) -> None:
    result = run([2], min_frames=1, frames=FRAMES)
    (row,) = result["objects"]
    assert row["object_seed"] == 2 and 2 <= len(row["materials"]) <= 4
    for policy in ("scripted", "active"):
        frames = Counter(row[policy]["finger_frames"])
        assert row[policy]["coverage"] == coverage(frames, row["materials"], 1)
        assert result["mean_coverage"][policy] == row[policy]["coverage"]
    out = tmp_path / "coverage.json"
    argv = ["touch_coverage", "--seeds", "2", "--frames", str(FRAMES), "--out", str(out)]
    monkeypatch.setattr(sys, "argv", argv)
    touch_coverage.main()
    assert json.loads(out.read_text()) == result


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--seeds", "1000"], "evaluation set"), (["--frames", "0"], "--frames=0 must be >= 1")],
)
def test_bad_arguments_exit_with_one_line(monkeypatch, capsys, args, message) -> None:
    monkeypatch.setattr(sys, "argv", ["touch_coverage", *args])
    with pytest.raises(SystemExit) as exit_info:
        touch_coverage.main()
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
