"""`make bench` writes one report whose every entry carries the load it was measured at."""

from __future__ import annotations

import json
import types

import neuralfeels_sem.bench.__main__ as bench_main


def test_discover_filters_by_substring() -> None:
    assert "bench_objects" in bench_main.discover(None)
    assert bench_main.discover(["objects"]) == ["bench_objects"]


def test_each_entry_records_its_wall_time_and_load(tmp_path, monkeypatch) -> None:
    """A working and a broken benchmark (fakes: the real ones take minutes)."""
    fakes = {
        "neuralfeels_sem.bench.bench_objects": types.SimpleNamespace(run=lambda: {"x_s": 1.0}),
        "neuralfeels_sem.bench.bench_pose": types.SimpleNamespace(run=lambda: 1 / 0),
    }
    monkeypatch.setattr(bench_main.importlib, "import_module", fakes.__getitem__)
    monkeypatch.setattr(bench_main, "collect_info", lambda: {"cpu_count": 2})
    out = tmp_path / "bench.json"
    assert bench_main.main(["--out", str(out), "--only", "objects", "pose"]) == 1
    results = json.loads(out.read_text())["results"]
    assert results["objects"]["x_s"] == 1.0
    assert results["pose"]["error"].startswith("ZeroDivisionError")
    for result in results.values():
        assert result["bench_wall_s"] >= 0 and result["load_average_1min"] >= 0
