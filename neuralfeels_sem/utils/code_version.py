"""The code a run ran: the git commit of the checkout and whether it had local changes.

Recorded in metrics.json (`code`) so the results page can say which commit its figures
come from. A copy outside git (an installed wheel, a tarball) records nulls. Read once per
process: a multirun imports the package once, so a commit made while it runs must not
relabel its later jobs, which still run the code it started with.
"""

from __future__ import annotations

import subprocess
from functools import cache
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1]
GIT_TIMEOUT_S = 5.0


def git_output(*args: str, repo: Path | None = None) -> str | None:
    """`git -C <repo> ARGS` stdout (repo: this package's checkout), or None when git, the
    checkout or what is asked is missing."""
    try:
        result = subprocess.run(
            ["git", "-C", str(repo or PACKAGE_DIR), *args],
            capture_output=True,
            text=True,
            timeout=GIT_TIMEOUT_S,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return result.stdout.strip() if result.returncode == 0 else None


@cache
def code_version() -> dict:
    """{"commit": 40-hex or None, "dirty": tracked files changed since it (None if unknown)},
    as of this process's first call (tasks call it when they start)."""
    commit = git_output("rev-parse", "HEAD")
    if commit is None:
        return {"commit": None, "dirty": None}
    # The whole checkout: conf/ and run.py shape a run as much as the package does.
    status = git_output("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit, "dirty": None if status is None else bool(status)}
