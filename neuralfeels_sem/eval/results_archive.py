"""The results page's inputs, kept in the repository so the page outlives its run outputs.

Run directories hold checkpoints and meshes (tens of MB a run) and stay on the machine
that made them; the page needs only a few kB of each run: its overrides, recorded config,
metrics, when it finished, its checkpoint's size and its touch plan. `save_source` writes
those of one source (a run or sweep directory) into one gzipped JSON file of the archive
(`docs/results_data/`), `load_archived` reads them back where the directory is gone, so
anyone with the repository can regenerate the page; `bench.json` reports are kept the same
way. Nothing here is unpickled: the archive is plain JSON.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.eval.results_runs import Run, Source, display_path
from neuralfeels_sem.utils.atomic import atomic_write

FORMAT = 1  # bump when a record's fields change meaning


def archive_name(label: str, suffix: str = ".json.gz") -> str:
    """One flat file name per source or bench path ('multirun/r32' -> 'multirun+r32.json.gz')."""
    clean = label.strip("/").replace("/", "+")
    if not clean or clean.startswith(".") or any(c in clean for c in '\\:*?"<>|'):
        raise DataError(f"{label}: cannot name an archive file after this path; rename it")
    return clean + suffix


def _write(path: Path, data: bytes) -> None:
    try:
        with atomic_write(path, "wb") as f:
            f.write(data)
    except OSError as exc:
        raise DataError(f"{path}: cannot write the archive ({exc.strerror})") from None


def _run_record(run: Run) -> dict:
    return {
        "path": display_path(run.path),
        "overrides": run.overrides,
        "config": run.config,
        "metrics": run.metrics,
        "finished_at": run.finished_at,
        "checkpoint_bytes": run.checkpoint_bytes,
        "touch_plan": run.touch_plan,
    }


def save_source(source: Source, archive_dir: Path) -> Path:
    """Write `source`'s page inputs to `archive_dir` (replacing an older copy)."""
    record = {
        "format": FORMAT,
        "path": source.label,
        "kind": source.kind,
        "failed": source.failed,
        "missing": source.missing,
        "runs": [_run_record(r) for r in source.runs],
    }
    out = archive_dir / archive_name(source.label)
    data = json.dumps(record, default=str).encode()  # key order kept: the page shows it
    # mtime=0: the same inputs give the same bytes, so an unchanged source is no git change
    _write(out, gzip.compress(data, mtime=0))
    return out


def load_archived(path: Path, archive_dir: Path) -> Source | None:
    """The archived copy of the source at `path` (None: never archived)."""
    file = archive_dir / archive_name(display_path(path))
    if not file.is_file():
        return None
    try:
        record = json.loads(gzip.decompress(file.read_bytes()))
    except (OSError, EOFError, ValueError) as exc:
        raise DataError(
            f"{file}: unreadable archive ({exc}); regenerate it from the runs"
        ) from None
    if record.get("format") != FORMAT:
        raise DataError(
            f"{file}: archive format {record.get('format')}, this version reads {FORMAT}"
        )
    # a record's keys are Run's fields (_run_record)
    runs = [Run(**{**r, "path": Path(r["path"])}) for r in record["runs"]]
    return Source(Path(record["path"]), record["kind"], runs, record["failed"], record["missing"])


def save_bench(path: Path, archive_dir: Path) -> None:
    """Keep a copy of a bench report (text as it is)."""
    _write(archive_dir / archive_name(display_path(path), ""), path.read_bytes())


def archived_bench(path: Path, archive_dir: Path) -> Path:
    """The archived copy of the bench report at `path` where there is one, else `path`
    (whose reading then fails with load_bench's one line)."""
    copy = archive_dir / archive_name(display_path(path), "")
    return copy if copy.is_file() else path
