"""Run directories, their lock, atomic writes and the signal handling, in process."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
from pathlib import Path

import pytest

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.pipeline.interrupts import Interrupted, StopOnSignal
from neuralfeels_sem.pipeline.segments import Segment, run_totals
from neuralfeels_sem.tasks.run_guard import check_run_dir
from neuralfeels_sem.utils.atomic import atomic_path, atomic_write, atomic_write_text
from neuralfeels_sem.utils.run_lock import LOCK_NAME, RunLock
from tests.reliability.checks import tree_digest


def _dead_pid() -> int:
    child = subprocess.Popen(["true"])
    child.wait()
    return child.pid


def _run_dir(tmp_path: Path) -> Path:
    run_dir = tmp_path / "run"
    (run_dir / "progression").mkdir(parents=True)
    (run_dir / "checkpoint.pt").write_bytes(b"weights")
    (run_dir / "metrics.json").write_text("{}")
    return run_dir


def test_a_new_or_empty_directory_is_accepted(tmp_path: Path) -> None:
    check_run_dir(tmp_path / "new", None)
    check_run_dir(tmp_path, None)  # exists, empty
    (tmp_path / LOCK_NAME).write_text("1\n")  # a lock alone holds no results
    check_run_dir(tmp_path, None)


@pytest.mark.parametrize(
    "resume, phrase",
    [
        (None, "already holds a run"),
        ("elsewhere/checkpoint.pt", "already holds a run"),
    ],
)
def test_a_directory_holding_a_run_is_refused(tmp_path: Path, resume, phrase: str) -> None:
    run_dir = _run_dir(tmp_path)
    with pytest.raises(ConfigError, match=phrase) as info:
        check_run_dir(run_dir, resume)
    assert "\n" not in str(info.value)
    assert f"mapping.resume={run_dir / 'checkpoint.pt'}" in str(info.value)


def test_a_start_that_failed_before_any_result_may_be_run_again(tmp_path: Path) -> None:
    """Hydra's config and log alone: an input the task refused after Hydra wrote them."""
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "config.yaml").write_text("object: {}\n")
    (tmp_path / "run.log").write_text("error: object.family='foo' is unknown\n")
    check_run_dir(tmp_path, None)
    (tmp_path / "touches.csv").write_text("frame\n")  # a result: refused, nothing to resume
    with pytest.raises(ConfigError, match="already holds a run .touches.csv.") as info:
        check_run_dir(tmp_path, None)
    assert "delete it (it holds no checkpoint to resume)" in str(info.value)
    assert "mapping.resume" not in str(info.value)


def test_resuming_the_run_a_directory_holds_continues_there(tmp_path: Path) -> None:
    run_dir = _run_dir(tmp_path)
    check_run_dir(run_dir, str(run_dir / "checkpoint.pt"))


def test_a_run_directory_that_is_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "run").write_text("x")
    with pytest.raises(ConfigError, match="is a file"):
        check_run_dir(tmp_path / "run", None)


def test_a_live_lock_refuses_a_second_process(tmp_path: Path) -> None:
    owner = subprocess.Popen(["sleep", "60"])
    try:
        (tmp_path / LOCK_NAME).write_text(f"{owner.pid}\n")
        with pytest.raises(ConfigError, match=f"in use by process {owner.pid}") as info:
            RunLock(tmp_path).acquire()
    finally:
        owner.kill()
        owner.wait()
    assert "\n" not in str(info.value)
    assert (tmp_path / LOCK_NAME).read_text() == f"{owner.pid}\n"  # left as it was


def test_a_lock_is_released_by_its_owner(tmp_path: Path) -> None:
    lock = RunLock(tmp_path)
    lock.acquire()
    assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"
    lock.release()
    assert not (tmp_path / LOCK_NAME).exists()


@pytest.mark.parametrize("content", ["dead", "", "garbled\n"])
def test_a_stale_lock_is_taken_over_with_a_warning(tmp_path: Path, caplog, content: str) -> None:
    stale = f"{_dead_pid()}\n" if content == "dead" else content
    (tmp_path / LOCK_NAME).write_text(stale)
    lock = RunLock(tmp_path)
    with caplog.at_level(logging.WARNING):
        lock.acquire()
    assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"
    assert "no longer runs" in caplog.text
    lock.release()


def test_release_leaves_another_process_lock_alone(tmp_path: Path) -> None:
    lock = RunLock(tmp_path)
    lock.acquire()
    (tmp_path / LOCK_NAME).write_text("1\n")  # taken over meanwhile
    lock.release()
    assert (tmp_path / LOCK_NAME).read_text() == "1\n"


def test_a_failed_atomic_write_keeps_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "metrics.json"
    atomic_write_text(path, '{"frames": 5}')
    before = tree_digest(tmp_path)
    with pytest.raises(RuntimeError), atomic_write(path) as f:
        f.write('{"fra')
        raise RuntimeError("killed mid-write")
    assert tree_digest(tmp_path) == before  # same content, no temporary left
    atomic_write_text(path, '{"frames": 6}')
    assert path.read_text() == '{"frames": 6}' and sorted(os.listdir(tmp_path)) == ["metrics.json"]


def test_atomic_paths_are_private_and_a_failed_write_keeps_the_old_file(tmp_path: Path) -> None:
    """Two writers of one file get their own temporary names (test workers may race)."""
    path = tmp_path / "model.onnx"
    path.write_bytes(b"old")
    with atomic_path(path) as first, atomic_path(path) as second:
        assert first != second and first.parent == second.parent == tmp_path
        first.write_bytes(b"first")
        second.write_bytes(b"second")
    assert path.read_bytes() == b"first"  # the outer writer finished last
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("killed mid-write")
    assert path.read_bytes() == b"first" and sorted(os.listdir(tmp_path)) == ["model.onnx"]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_the_first_signal_asks_to_stop_the_second_stops(tmp_path: Path, signum: int) -> None:
    before = signal.getsignal(signum)
    with StopOnSignal(tmp_path) as stop:
        os.kill(os.getpid(), signum)
        assert stop.requested and stop.signum == signum
        with pytest.raises(Interrupted) as info:
            os.kill(os.getpid(), signum)
    assert info.value.exit_code == 128 + signum
    assert str(tmp_path / "checkpoint.pt") in str(info.value)
    assert signal.getsignal(signum) == before  # restored


def test_segments_add_up_to_the_whole_run() -> None:
    first, second = Segment(), Segment()
    for index in range(3):
        first.add_frame(index, 0.1 * index)
    first.wall_s, first.partial = 2.0, True
    for index in range(3, 8):
        second.add_frame(index, 0.1 * index)
    second.wall_s = 3.0
    totals = run_totals([first, second], frame_period_s=0.1)
    assert totals["frames"] == 8 and totals["wall_s"] == pytest.approx(5.0)
    assert totals["sensor_time_s"] == pytest.approx(0.8)
    assert totals["realtime_factor"] == pytest.approx(0.8 / 5.0)
    assert [s["partial"] for s in totals["segments"]] == [True, False]
