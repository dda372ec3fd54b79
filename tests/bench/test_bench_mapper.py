"""The default run's realtime factor in `make bench`: the median of repeated runs."""

from __future__ import annotations

import pytest

from neuralfeels_sem.bench import bench_mapper


def _fake_runs(monkeypatch: pytest.MonkeyPatch, results: list[dict]) -> None:
    queue = list(results)
    monkeypatch.setattr(bench_mapper, "_default_run", lambda *overrides: queue.pop(0))


def test_the_median_run_is_reported_with_every_factor(monkeypatch: pytest.MonkeyPatch) -> None:
    runs = [
        {"realtime_factor": 0.46, "loop_wall_s": 43.5, "matching_mean_class_pct": 95.4},
        {"realtime_factor": 0.54, "loop_wall_s": 37.1, "matching_mean_class_pct": 95.4},
        {"realtime_factor": 0.51, "loop_wall_s": 39.2, "matching_mean_class_pct": 95.4},
    ]
    _fake_runs(monkeypatch, runs)
    out = bench_mapper._repeated_default_run(3)
    assert out["realtime_factor"] == 0.51 and out["loop_wall_s"] == 39.2
    assert out["realtime_factor_runs"] == [0.46, 0.54, 0.51]
    assert (out["realtime_factor_min"], out["realtime_factor_max"]) == (0.46, 0.54)


def test_a_failed_repeat_is_reported_instead_of_a_median(monkeypatch: pytest.MonkeyPatch) -> None:
    _fake_runs(monkeypatch, [{"realtime_factor": 0.5}, {"error": "exit 2: bad config"}])
    assert bench_mapper._repeated_default_run(2) == {"error": "exit 2: bad config"}


def test_the_busy_shares_come_from_the_threads_cpu_time() -> None:
    metrics = {"wall_s": 40.0, "producer_cpu_s": 32.0, "mapper_cpu_s": 31.3}
    assert bench_mapper._busy(metrics, "producer_cpu_s") == 0.8
    assert bench_mapper._busy(metrics, "mapper_cpu_s") == 0.782
    assert bench_mapper._busy({"wall_s": 40.0}, "mapper_cpu_s") is None  # an older run


def test_the_producer_stage_shares_come_from_its_cpu_time_by_stage() -> None:
    metrics = {"wall_s": 40.0, "producer_stage_cpu_s": {"acquire": 10.0, "classify": 20.5}}
    assert bench_mapper._stage_busy(metrics) == {"acquire": 0.25, "classify": 0.512}
    assert bench_mapper._stage_busy({"wall_s": 40.0}) == {}  # an older run
