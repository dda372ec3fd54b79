"""A `-m` sweep of two tiny jobs finishes with every job's outputs and the aggregate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.helpers import run_cli

TINY_JOB = ["task=info"]


# submitit_local starts a process per job (about 30 s on 2 cores): a `slow` case; the
# default run keeps the basic launcher, which shares the sweep and aggregation code.
@pytest.mark.parametrize(
    "launcher", ["local", pytest.param("submitit_local", marks=pytest.mark.slow)]
)
def test_multirun_two_jobs_and_aggregate(tmp_path: Path, launcher: str) -> None:
    sweep_dir = tmp_path / "sweep"
    result = run_cli(
        ["-m", *TINY_JOB, "seed=0,1", f"launcher={launcher}", f"hydra.sweep.dir={sweep_dir}"]
    )
    assert result.returncode == 0, result.stderr[-3000:]
    for job in ("0", "1"):
        assert (sweep_dir / job / "info.json").exists(), sorted(
            p.name for p in (sweep_dir / job).iterdir()
        )
        assert (sweep_dir / job / ".hydra" / "config.yaml").exists()
    summary = json.loads((sweep_dir / "summary.json").read_text())
    assert [j["status"] for j in summary["jobs"]] == ["ok", "ok"]
    assert summary["failed"] == []
    # Both jobs differ only by seed, so they form one group of two trials.
    assert len(summary["groups"]) == 1
    assert summary["groups"][0]["metrics"]["cpu_count"]["n"] == 2
    assert (sweep_dir / "summary.csv").read_text().startswith("metric,mean,std,n")
    assert (sweep_dir / "summary.png").stat().st_size > 1000


def test_aggregate_marks_corrupt_and_failed_jobs(tmp_path: Path) -> None:
    from neuralfeels_sem.eval.aggregate import summarize

    for job, content in (("0", '{"matching_pct": 90.0}'), ("1", '{"matching_pct": 8'), ("2", None)):
        (tmp_path / job / ".hydra").mkdir(parents=True)
        (tmp_path / job / ".hydra" / "overrides.yaml").write_text(f"- seed={job}\n")
        if content is None:
            (tmp_path / job / "error.txt").write_text("DataError: boom\n")
        else:
            (tmp_path / job / "metrics.json").write_text(content)
    summary = summarize(tmp_path)
    assert [j["status"] for j in summary["jobs"]] == ["ok", "failed", "failed"]
    assert summary["failed"] == ["1", "2"]
    assert summary["groups"][0]["metrics"]["matching_pct"] == {"mean": 90.0, "std": 0.0, "n": 1}


def test_aggregate_lists_jobs_in_number_order(tmp_path: Path) -> None:
    """Job 2 before job 10, so the maps grid and the summary follow the sweep's order."""
    from neuralfeels_sem.eval.aggregate import summarize

    for job in ("0", "1", "2", "10", "11"):
        (tmp_path / job / ".hydra").mkdir(parents=True)
        (tmp_path / job / ".hydra" / "overrides.yaml").write_text(f"- seed={job}\n")
        (tmp_path / job / "metrics.json").write_text('{"matching_pct": 90.0}')
    (tmp_path / "plots").mkdir()  # not a job: no overrides
    assert [j["job"] for j in summarize(tmp_path)["jobs"]] == ["0", "1", "2", "10", "11"]
