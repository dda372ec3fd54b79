"""The command line refuses a bad resume or run directory within seconds, before set-up.

Each case: exit code 2, one stderr line naming the problem, no traceback, and the earlier
run's directory byte for byte as it was. The refusals happen before Hydra writes its
config or log, so nothing at all is written.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from neuralfeels_sem.utils.run_lock import LOCK_NAME
from tests.helpers import run_cli
from tests.reliability.checks import assert_refused, provenance_of, tree_digest, write_run_dir

# Never reached by a refused run; keeps an accepted one (a failing check) short.
TINY = ["sensor.duration_s=0.3", "classifier=oracle"]


@pytest.fixture(scope="module")
def earlier_run(tmp_path_factory) -> Path:
    """A plushie/sim run directory with the default classes and model."""
    run_dir = tmp_path_factory.mktemp("earlier") / "run"
    write_run_dir(run_dir, provenance_of([]))
    return run_dir


def _object(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return (
        [f"mapping.resume={run / 'checkpoint.pt'}", "object=patched_toy"],
        ["object plushie (hash", "this run is patched_toy (hash", "object=plushie"],
    )


def _existing_dir(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return ([f"hydra.run.dir={run}"], [f"hydra.run.dir={run} already holds a run"])


def _missing_resume(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return ([f"mapping.resume={tmp / 'nope' / 'checkpoint.pt'}"], ["does not exist"])


def _live_lock(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    # The test process itself is the live owner.
    (tmp / "locked").mkdir()
    (tmp / "locked" / LOCK_NAME).write_text(f"{os.getpid()}\n")
    return ([f"hydra.run.dir={tmp / 'locked'}"], [f"in use by process {os.getpid()}"])


def _classes(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return (
        [f"mapping.resume={run / 'checkpoint.pt'}", "materials=[fabric,plastic,metal]"],
        ["[fabric,plastic,metal]", "materials=[", "or start a new run"],
    )


def _model(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return (
        [f"mapping.resume={run / 'checkpoint.pt'}", "model.sdf.hidden_dim=32"],
        ["different model", "model.sdf.hidden_dim:", "32 here"],
    )


def _dir_is_file(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    (tmp / "a_file").write_text("x")
    return ([f"hydra.run.dir={tmp / 'a_file'}"], ["is a file"])


def _resume_is_dir(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    return ([f"mapping.resume={run}"], ["is a directory", "checkpoint.pt"])


def _resume_garbage(run: Path, tmp: Path) -> tuple[list[str], list[str]]:
    (tmp / "checkpoint.pt").write_bytes(b"\x80\x04not a pickle")
    return ([f"mapping.resume={tmp / 'checkpoint.pt'}"], ["is unreadable"])


CASES = {
    "object": _object,
    "existing_dir": _existing_dir,
    "missing_resume": _missing_resume,
    "live_lock": _live_lock,
}
SLOW_CASES = {
    "classes": _classes,
    "model": _model,
    "dir_is_file": _dir_is_file,
    "resume_is_dir": _resume_is_dir,
    "resume_garbage": _resume_garbage,
}
PARAMS = [pytest.param(name, id=name) for name in CASES] + [
    pytest.param(name, id=name, marks=pytest.mark.slow) for name in SLOW_CASES
]


@pytest.mark.parametrize("case", PARAMS)
def test_refused_in_one_line_with_nothing_changed(
    earlier_run: Path, tmp_path: Path, case: str
) -> None:
    args, names = {**CASES, **SLOW_CASES}[case](earlier_run, tmp_path)
    before, before_tmp = tree_digest(earlier_run), tree_digest(tmp_path)
    result = run_cli([*TINY, *args], timeout=120)
    assert_refused(result, 2, *names)
    assert tree_digest(earlier_run) == before
    assert tree_digest(tmp_path) == before_tmp


def test_a_start_refused_after_hydra_wrote_its_config_is_run_again_there(tmp_path: Path) -> None:
    """An input the task refuses itself (an unknown shape family, checked where the object is
    generated) leaves Hydra's config and log behind; the same directory then takes the next
    command instead of calling that failed start a run to resume."""
    run_dir = tmp_path / "run"
    args = [*TINY, "object=random", "object.family=foo", f"hydra.run.dir={run_dir}"]
    for _ in range(2):
        result = run_cli(args, timeout=120)
        assert_refused(result, 2, "object.family='foo' is unknown")
    assert sorted(p.name for p in run_dir.iterdir() if p.name != LOCK_NAME) == [".hydra", "run.log"]
