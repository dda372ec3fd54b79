"""Shared test fixtures. Everything here runs on a CPU with no hardware attached."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("MUJOCO_GL", "egl")
# One torch thread, as a run's default (`threads=auto`) and as make test's workers (one per
# core) have: a test that maps in-process then computes what a run computes.
os.environ.setdefault("OMP_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

from neuralfeels_sem.utils.paths import REPO_DIR, SHARED_DATA_DIR  # noqa: E402
from neuralfeels_sem.utils.seed import seed_everything  # noqa: E402

CONF_DIR = REPO_DIR / "conf"


@pytest.fixture(autouse=True)
def _seeded() -> None:
    """Every test starts from seeded RNGs, as a run's task does (tasks/runner.py): a test
    that builds a field or maps in-process gets the same initial weights each time."""
    seed_everything(0)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Real third-party data beside the project (../shared/data); skip where absent."""
    if not SHARED_DATA_DIR.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA_DIR} is absent")
    return SHARED_DATA_DIR


@pytest.fixture(scope="session")
def conf_dir() -> Path:
    return CONF_DIR
