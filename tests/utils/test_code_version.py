"""code_version: the checkout's commit and local changes; nulls outside git."""

from __future__ import annotations

import subprocess

import pytest

from neuralfeels_sem.utils import code_version as cv


@pytest.fixture(autouse=True)
def fresh_process():
    """Each test reads the version as a new process would (it is cached per process)."""
    cv.code_version.cache_clear()
    yield
    cv.code_version.cache_clear()


def test_a_git_checkout_gives_its_head_commit() -> None:
    head = subprocess.run(
        ["git", "-C", str(cv.PACKAGE_DIR), "rev-parse", "HEAD"], capture_output=True, text=True
    )
    if head.returncode != 0:
        pytest.skip("the package is not in a git checkout here")
    version = cv.code_version()
    assert version["commit"] == head.stdout.strip() and isinstance(version["dirty"], bool)


def test_outside_git_the_version_is_null(monkeypatch, tmp_path) -> None:
    monkeypatch.setattr(cv, "PACKAGE_DIR", tmp_path)
    assert cv.code_version() == {"commit": None, "dirty": None}


def test_without_git_installed_the_version_is_null(monkeypatch) -> None:
    monkeypatch.setenv("PATH", "")
    assert cv.code_version() == {"commit": None, "dirty": None}


def test_the_version_is_read_once_per_process(monkeypatch) -> None:
    # A multirun imports the code once: a commit made during it must not relabel its
    # later jobs, which still run the code the process started with.
    answers = iter(["a" * 40, "", "b" * 40, ""])
    monkeypatch.setattr(cv, "git_output", lambda *args: next(answers))
    first = cv.code_version()
    assert first == {"commit": "a" * 40, "dirty": False}
    assert cv.code_version() == first
