"""Atomic file writes: a reader (or a run killed mid-write) sees the old file or the new
one, never half of one."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO


@contextmanager
def atomic_write(path: str | Path, mode: str = "w", newline: str | None = None) -> Iterator[IO]:
    """Open `<path>.tmp` for writing; on a clean exit flush it to disk and rename it over `path`.

    On an exception the temporary file is removed and `path` keeps its previous content.
    Writers that need a file name's extension take the file object instead (savefig with
    `format=`, trimesh export with `file_type=`, np.savez with a file object).
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_write mode must be 'w' or 'wb', not {mode!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, mode, newline=newline) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary file name beside `path`, of this process's own, for writers that take a
    name (torch.save, torch.onnx.export) or open the file themselves; renamed over `path`
    on a clean exit, removed otherwise. Unlike atomic_write's fixed `<path>.tmp`, parallel
    writers of one file (test workers, sweep jobs) never share it. Raises OSError where the
    folder is not writable."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


def atomic_write_text(path: str | Path, text: str) -> None:
    with atomic_write(path) as f:
        f.write(text)
