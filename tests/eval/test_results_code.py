"""A simulated run from before a keyless behaviour change is not a run of today's code."""

from __future__ import annotations

import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from neuralfeels_sem.eval import results_code
from neuralfeels_sem.eval.results_code import (
    BEHAVIOUR_CHANGES,
    BehaviourChange,
    code_drift,
    contains,
)
from neuralfeels_sem.eval.results_page import drift_lines
from neuralfeels_sem.utils.code_version import git_output
from neuralfeels_sem.utils.paths import REPO_DIR

SIM = {"sensor.name": "sim"}


def commit(repo: Path, message: str) -> str:
    def git(*args: str) -> str:
        cmd = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@example.org"]
        done = subprocess.run([*cmd, *args], capture_output=True, text=True, check=True)
        return done.stdout.strip()

    git("commit", "-q", "--allow-empty", "-m", message)
    return git("rev-parse", "HEAD")


@pytest.fixture
def history(tmp_path: Path, monkeypatch) -> tuple[str, str, str]:
    """Commits before, making and after a rig change, listed as today's only change."""
    subprocess.run(["git", "-C", str(tmp_path), "init", "-q"], check=True)
    before, change, after = (commit(tmp_path, m) for m in ("before", "fix", "after"))
    monkeypatch.setattr(
        results_code, "BEHAVIOUR_CHANGES", {"sim.rig": BehaviourChange(change, "sim", "fix")}
    )
    contains.cache_clear()
    return before, change, after


def test_a_run_before_the_change_shows_it_as_its_setting(tmp_path: Path, history) -> None:
    before, change, after = history
    short = change[:7]
    assert code_drift(SIM, before, tmp_path) == {"sim.rig": (f"before@{short}", f"since@{short}")}
    assert code_drift(SIM, change, tmp_path) == {}
    assert code_drift(SIM, after, tmp_path) == {}


def test_other_sensors_and_unknown_commits_are_taken_as_today(tmp_path: Path, history) -> None:
    before, _, _ = history
    assert code_drift({"sensor.name": "real"}, before, tmp_path) == {}  # no simulated rig
    assert code_drift(SIM, None, tmp_path) == {}  # no commit recorded
    assert code_drift(SIM, "0" * 40, tmp_path) == {}  # a commit this clone lacks
    assert code_drift(SIM, before, tmp_path / "not-a-repo") == {}


def test_every_listed_change_is_a_commit_of_this_repository() -> None:
    if git_output("rev-parse", "HEAD", repo=REPO_DIR) is None:
        pytest.skip("not a git checkout")
    head = git_output("rev-parse", "HEAD", repo=REPO_DIR)
    for key, (change, sensor, what) in BEHAVIOUR_CHANGES.items():
        assert len(change) == 40 and sensor and what, key
        found = contains(head, change)
        if found is None:
            pytest.skip("the checkout's history is too shallow to hold the change")
        assert found, f"{key}: {change} is not in this checkout's history"


def test_the_page_says_what_a_keyless_change_changed() -> None:
    change, _, what = BEHAVIOUR_CHANGES["sim.rig"]
    then, now = f"before@{change[:7]}", f"since@{change[:7]}"
    run = SimpleNamespace(drift={"sim.rig": (then, now), "sensor.duration_s": (20.0, 30.0)})
    (line,) = drift_lines([run])
    assert f"`sim.rig` {then} (today {now}) ({what})" in line
    assert "`sensor.duration_s` 20.0 (today 30.0);" in line  # a config key needs no words
