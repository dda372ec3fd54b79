"""On-disk cache of generated objects under data/objects/ (gitignored).

A fresh process (a CLI run, a sweep job, a test session) loads a shipped object in
milliseconds instead of regenerating it. Entries are keyed by a hash of the code that
generates them, so editing a recipe or the mesher never serves a stale mesh; a file
that cannot be read or written is ignored and the object is regenerated.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from neuralfeels_sem.utils import paths

log = logging.getLogger(__name__)

_SOURCES = ("procedural.py", "sdf.py", "regions.py", "library.py")


def code_version() -> str:
    """Hash of the generating modules' source (12 hex digits)."""
    digest = hashlib.sha256()
    for name in _SOURCES:
        digest.update((Path(__file__).parent / name).read_bytes())
    return digest.hexdigest()[:12]


def entry_path(name: str) -> Path:
    return paths.CACHE_DIR / "objects" / f"{name}-{code_version()}.npz"


def load(path: Path, keys: tuple[str, ...]) -> dict[str, np.ndarray] | None:
    """The cached arrays `keys`, or None when absent, unreadable or incomplete."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in keys}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:  # regenerate
        log.warning("ignoring unreadable object cache %s (%s)", path, exc)
        return None


def save(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write atomically (temp file + rename), so parallel jobs never read half a file."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except OSError as exc:  # read-only install, full disk: caching is optional
        log.warning("could not cache object at %s (%s)", path, exc)
