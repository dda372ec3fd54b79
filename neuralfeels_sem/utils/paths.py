"""Where the project keeps shipped assets, generated caches and the shared real data."""

import hashlib
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1]
REPO_DIR = PACKAGE_DIR.parent
ASSETS_DIR = PACKAGE_DIR / "assets"
# Generated on first use, never committed (see .gitignore).
CACHE_DIR = REPO_DIR / "data"
# Real third-party data beside the project; absent on a user's fresh clone.
SHARED_DATA_DIR = REPO_DIR.parent / "shared" / "data"


def cache_dir(*parts: str) -> Path:
    path = CACHE_DIR.joinpath(*parts)
    path.mkdir(parents=True, exist_ok=True)
    return path


def file_digest(path: Path) -> str:
    """A short content hash of a file: the name of what a cache derives from it (a traced
    or exported network is stale once its checkpoint's bytes change)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]
