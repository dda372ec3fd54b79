"""A run that loaded other shipped weights than today's is not a run of today's defaults."""

from __future__ import annotations

import subprocess
from pathlib import Path

from neuralfeels_sem.eval.results_weights import SHIPPED, blob_at, weights_drift

CLASSIFIER = SHIPPED["classifier.checkpoint"]


def git(repo: Path, *args: str) -> str:
    done = subprocess.run(
        ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@example.org", *args],
        capture_output=True,
        text=True,
        check=True,
    )
    return done.stdout.strip()


def commit_weights(repo: Path, content: bytes) -> str:
    path = repo / CLASSIFIER
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content)
    git(repo, "add", CLASSIFIER)
    git(repo, "commit", "-q", "-m", "weights")
    return git(repo, "rev-parse", "HEAD")


def test_weights_of_another_commit_are_a_changed_default(tmp_path: Path) -> None:
    git(tmp_path, "init", "-q")
    old = commit_weights(tmp_path, b"stage 7")
    new = commit_weights(tmp_path, b"stage 8")
    then, now = blob_at(old, CLASSIFIER, tmp_path), blob_at(new, CLASSIFIER, tmp_path)
    assert then and now and then != now
    assert weights_drift({"classifier.checkpoint": None}, {}, old, tmp_path) == {
        "classifier.checkpoint": (f"shipped@{then[:7]}", f"shipped@{now[:7]}")
    }
    # the tactile depth network's file is absent here: nothing to compare
    assert weights_drift({}, {}, new, tmp_path) == {}


def test_runs_that_did_not_load_the_shipped_weights_or_cannot_tell_are_taken_at_their_word(
    tmp_path: Path,
) -> None:
    git(tmp_path, "init", "-q")
    old = commit_weights(tmp_path, b"stage 7")
    commit_weights(tmp_path, b"stage 8")
    own = {"classifier.checkpoint": "/data/mine.pt"}
    assert weights_drift(own, {}, old, tmp_path) == {}  # its own checkpoint, recorded
    assert weights_drift({}, {"classifier.checkpoint": "/data/mine.pt"}, old, tmp_path) == {}
    assert weights_drift({}, {}, None, tmp_path) == {}  # no commit recorded
    assert weights_drift({}, {}, "0" * 40, tmp_path) == {}  # a commit this clone lacks
    assert weights_drift({}, {}, old, tmp_path / "not-a-repo") == {}
