"""The terminal summary's busy rows: each thread's CPU time as a share of the loop's wall
time, and at realtime what the pace gave up."""

from __future__ import annotations

from neuralfeels_sem.viz.run_report import _busy, _pace_rows, _stages


def test_busy_shares_name_the_thread_that_bounds_the_loop() -> None:
    metrics = {"wall_s": 10.0, "producer_cpu_s": 9.5, "mapper_cpu_s": 4.0}
    assert _busy(metrics) == "95.0% / 40.0%"


def test_runs_without_thread_times_show_none() -> None:
    assert _busy({"wall_s": 10.0}) == "n/a"  # a metrics.json from before the fields
    assert _busy({"wall_s": 0.0, "producer_cpu_s": 1.0, "mapper_cpu_s": 1.0}) == "n/a"


def test_the_producer_stages_as_shares_of_the_loop() -> None:
    stages = {"acquire": 3.0, "classify": 4.5, "perceive": 1.25}
    assert _stages({"wall_s": 10.0, "producer_stage_cpu_s": stages}) == "30%/45%/12%"
    assert _stages({"wall_s": 10.0}) == "n/a"  # a metrics.json from before the field


def test_realtime_runs_add_what_the_pace_gave_up() -> None:
    metrics = {"pace": "realtime", "frames_dropped": 200, "touch_frames": 90, "lag_max_s": 1.234}
    assert _pace_rows(metrics) == [
        ("frames dropped / touches kept", "200 / 90", "", ""),
        ("largest lag", "1.23 s", "", ""),
    ]
    assert _pace_rows({"pace": "offline", "frames_dropped": 0}) == []
