"""The results page's archive: a page regenerated after its run directories are gone."""

from __future__ import annotations

import gzip
import json
import shutil
from pathlib import Path

import pytest

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.eval.results_archive import archive_name, load_archived, save_source
from neuralfeels_sem.eval.results_runs import load_source
from neuralfeels_sem.tasks.results_page import main
from tests.eval.test_results_page import write_bench, write_object_sweep


@pytest.fixture
def object_sweep(tmp_path: Path) -> Path:
    return write_object_sweep(tmp_path)


def page(tmp_path: Path, name: str, *args: str) -> str:
    out = tmp_path / name
    assert main(["--out", str(out), *args]) == 0
    return out.read_text()


def test_a_page_regenerates_from_the_archive_once_its_runs_are_gone(
    tmp_path: Path, object_sweep: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # sources are named relative to the working directory
    (object_sweep / "0" / "touch_suggestions.json").write_text(
        json.dumps({"touch_plan": {"regrasps": [1.5, 4.0]}})
    )
    (object_sweep / "0" / "checkpoint.pt").write_bytes(b"x" * 2048)
    bench = write_bench(tmp_path / "bench.json", {"mapper": {"steps_per_s": 8.04}})
    archive = tmp_path / "docs" / "results_data"
    args = ["--archive", str(archive), "--bench", "bench.json", "multirun/mm"]
    before = page(tmp_path, "before.md", *args)
    assert "--archive " in before.split("```")[1]
    kept = sorted(p.name for p in archive.iterdir())
    assert kept == ["bench.json", "multirun+mm.json.gz"]
    run = load_archived(Path("multirun/mm"), archive).runs[0]
    assert run.touch_plan == {"regrasps": [1.5, 4.0]} and run.checkpoint_bytes == 2048
    assert run.finished_at == (object_sweep / "0" / "metrics.json").stat().st_mtime
    shutil.rmtree(object_sweep)
    bench.unlink()
    after = page(tmp_path, "after.md", *args)
    assert after.replace("after.md", "before.md") == before
    # The same inputs give the same archive bytes: regenerating is no git change.
    saved = (archive / "multirun+mm.json.gz").read_bytes()
    save_source(load_archived(Path("multirun/mm"), archive), archive)
    assert (archive / "multirun+mm.json.gz").read_bytes() == saved


def test_without_a_directory_or_a_copy_the_page_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main(["--archive", str(tmp_path / "a"), str(tmp_path / "gone")]) == 2
    assert "no such directory, and no copy of it in" in capsys.readouterr().err
    assert main([str(tmp_path / "gone")]) == 2  # without --archive: the directory's error


def test_a_damaged_or_foreign_archive_is_a_data_error(tmp_path: Path, object_sweep: Path) -> None:
    archive = tmp_path / "archive"
    file = save_source(load_source(object_sweep), archive)
    name = Path(file.name.removesuffix(".json.gz").replace("+", "/"))
    assert len(load_archived(name, archive).runs) == 8
    record = json.loads(gzip.decompress(file.read_bytes()))
    file.write_bytes(gzip.compress(json.dumps(record | {"format": 99}).encode()))
    with pytest.raises(DataError, match="archive format 99"):
        load_archived(name, archive)
    file.write_bytes(b"not gzip")
    with pytest.raises(DataError, match="unreadable archive"):
        load_archived(name, archive)
    assert load_archived(Path("multirun/other"), archive) is None


def test_archive_names_are_flat_and_refuse_odd_paths() -> None:
    assert archive_name("multirun/r32_dev") == "multirun+r32_dev.json.gz"
    assert archive_name("bench.json", "") == "bench.json"
    for bad in ("", "/", "../x", "a:b"):
        with pytest.raises(DataError):
            archive_name(bad)
