"""What every reliability case asserts: the exit code, one stderr line naming the problem,
no traceback, and that no file the earlier run wrote changed."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

from neuralfeels_sem.mapping.checkpoint import save_checkpoint
from neuralfeels_sem.mapping.provenance import Provenance
from neuralfeels_sem.tasks.run_guard import run_provenance
from tests.helpers import compose_config
from tests.mapping.synthetic import small_mapper


def tree_digest(directory: Path) -> dict[str, str]:
    """Every file under `directory` (relative path) -> the sha256 of its bytes."""
    if not directory.exists():
        return {}
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }


def assert_refused(result: subprocess.CompletedProcess, exit_code: int, *names: str) -> str:
    """One stderr line (returned) holding every one of `names`, no traceback, `exit_code`."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode == exit_code, result.stderr[-2000:]
    assert "Traceback" not in result.stderr and "Traceback" not in result.stdout
    assert len(lines) == 1, result.stderr[-2000:]
    for name in names:
        assert name in lines[0], (name, lines[0])
    return lines[0]


def provenance_of(overrides: list[str]) -> Provenance:
    """The provenance a task=map run with `overrides` records (object built, hashed)."""
    from hydra.utils import instantiate

    cfg = compose_config(overrides)
    return run_provenance(cfg, instantiate(cfg.object))


def write_run_dir(run_dir: Path, provenance: Provenance | None) -> Path:
    """A run directory as a map run leaves it (checkpoint, metrics, config), at toy size.

    The guard reads only the checkpoint's provenance, so the field inside may be small.
    """
    run_dir.mkdir(parents=True)
    save_checkpoint(
        run_dir / "checkpoint.pt", small_mapper(), 4, {"segments": []}, None, provenance
    )
    (run_dir / "metrics.json").write_text('{"frames": 5}\n')
    (run_dir / ".hydra").mkdir()
    (run_dir / ".hydra" / "config.yaml").write_text("task:\n  name: map\n")
    return run_dir / "checkpoint.pt"
