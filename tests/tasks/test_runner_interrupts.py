"""A signal that lands inside a lazy import ends the run as an interruption (tasks/runner.py)."""

from __future__ import annotations

import signal

import pytest

from neuralfeels_sem.pipeline.interrupts import Interrupted
from neuralfeels_sem.tasks import runner


def _import_interrupted_by(interruption: BaseException) -> ImportError:
    """What a C extension's init raises when a signal interrupts it (mujoco's does this)."""
    try:
        try:
            raise interruption
        except BaseException as exc:
            raise ImportError("initialization failed") from exc
    except ImportError as exc:
        return exc


def test_the_interruption_behind_an_import_error_is_found() -> None:
    ctrl_c = KeyboardInterrupt()
    assert runner._interruption_behind(_import_interrupted_by(ctrl_c)) is ctrl_c
    term = Interrupted(signal.SIGTERM, "terminated (SIGTERM)")
    assert runner._interruption_behind(RuntimeError("not a signal")) is None
    assert runner._interruption_behind(_import_interrupted_by(term)) is term


def test_an_interruption_ends_in_one_line_and_its_exit_code(capsys, monkeypatch) -> None:
    monkeypatch.setattr(runner, "output_dir", lambda: "outputs/run")
    with pytest.raises(SystemExit) as ctrl_c:
        runner._end_interrupted(KeyboardInterrupt())
    assert ctrl_c.value.code == 130
    with pytest.raises(SystemExit) as term:
        runner._end_interrupted(Interrupted(signal.SIGTERM, "terminated (SIGTERM)"))
    assert term.value.code == 128 + signal.SIGTERM
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [
        "interrupted (SIGINT); outputs written so far are in outputs/run",
        "terminated (SIGTERM)",
    ]
