"""Shared test fixtures. Everything here runs on a CPU with no hardware attached."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("MUJOCO_GL", "egl")
if "PYTEST_XDIST_WORKER" in os.environ:
    # Parallel workers already fill the cores; more than one torch thread each only
    # oversubscribes them (make test runs one worker per core).
    os.environ.setdefault("OMP_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

import pytest  # noqa: E402

from neuralfeels_sem.utils.paths import REPO_DIR, SHARED_DATA_DIR  # noqa: E402

CONF_DIR = REPO_DIR / "conf"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Real third-party data beside the project (../shared/data); skip where absent."""
    if not SHARED_DATA_DIR.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA_DIR} is absent")
    return SHARED_DATA_DIR


@pytest.fixture(scope="session")
def conf_dir() -> Path:
    return CONF_DIR
