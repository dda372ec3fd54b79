"""The on-disk object cache: round trip, served instead of regenerating, robust to bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.objects import disk_cache, library
from neuralfeels_sem.utils import paths


@pytest.fixture
def cache_root(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setattr(paths, "CACHE_DIR", tmp_path)
    library._generate.cache_clear()
    yield tmp_path
    library._generate.cache_clear()


def test_round_trip_and_bad_files(tmp_path: Path) -> None:
    arrays = {"vertices": np.arange(6.0).reshape(2, 3), "names": np.array(["fabric", "ignore"])}
    disk_cache.save(path := tmp_path / "sub" / "x.npz", arrays)
    loaded = disk_cache.load(path, ("vertices", "names"))
    assert loaded is not None and set(loaded) == set(arrays)
    for key, value in arrays.items():
        np.testing.assert_array_equal(loaded[key], value)
    assert list(path.parent.glob("*.tmp")) == []
    assert disk_cache.load(path, ("vertices", "faces")) is None  # written by older code
    path.write_bytes(path.read_bytes()[:40])  # truncated by a crash
    assert disk_cache.load(path, ("vertices",)) is None
    assert disk_cache.load(tmp_path / "absent.npz", ("vertices",)) is None
    blocker = tmp_path / "file"
    blocker.write_text("")
    disk_cache.save(blocker / "x.npz", arrays)  # parent is a file: warns, does not raise


def test_code_version_names_the_entry() -> None:
    version = disk_cache.code_version()
    assert len(version) == 12 and int(version, 16) >= 0
    assert disk_cache.entry_path("plushie").name == f"plushie-{version}.npz"


def test_generate_writes_then_serves_from_disk(cache_root: Path, monkeypatch) -> None:
    first = library._generate("powder_shaker")
    entry = disk_cache.entry_path("powder_shaker")
    assert entry.is_file() and entry.is_relative_to(cache_root)
    library._generate.cache_clear()

    def fail(name: str):
        raise AssertionError("regenerated although the disk cache holds the object")

    monkeypatch.setattr(library, "build_arrays", fail)
    second = library._generate("powder_shaker")
    for a, b in zip(first[:3], second[:3]):
        np.testing.assert_array_equal(a, b)
        assert not b.flags.writeable
    assert second[3] == first[3] == "metal"
