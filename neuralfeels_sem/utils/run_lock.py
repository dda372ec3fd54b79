"""A lock file holding the pid of the process that owns a run directory.

A second process on the same directory is refused; a lock left by a process that no
longer exists (killed with -9, machine rebooted) is taken over, with a warning.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from neuralfeels_sem.core.errors import ConfigError

log = logging.getLogger(__name__)

LOCK_NAME = "run.lock"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by another user
        return True
    return True


def _read_pid(path: Path) -> int | None:
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None  # empty or garbled: its writer died between create and write


class RunLock:
    """Owns `<directory>/run.lock` from `acquire()` until `release()`."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self.path = self.directory / LOCK_NAME
        self.held = False

    def acquire(self) -> None:
        """Take the lock. Raises ConfigError when a live process holds it."""
        for _ in range(2):  # the second try follows the removal of a stale lock
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._take_over_if_stale()
                continue
            with os.fdopen(fd, "w") as f:
                f.write(f"{os.getpid()}\n")
            self.held = True
            return
        raise ConfigError(
            f"run directory {self.directory}: could not take {LOCK_NAME}; choose another hydra.run.dir"
        )

    def _take_over_if_stale(self) -> None:
        pid = _read_pid(self.path)
        if pid is not None and pid != os.getpid() and _pid_alive(pid):
            raise ConfigError(
                f"run directory {self.directory} is in use by process {pid} ({self.path}); "
                "wait for it to end or choose another hydra.run.dir"
            )
        log.warning(
            "run directory %s: taking over the lock of process %s, which no longer runs",
            self.directory,
            pid,
        )
        self.path.unlink(missing_ok=True)

    def release(self) -> None:
        """Remove the lock if this process still owns it."""
        if self.held and _read_pid(self.path) == os.getpid():
            self.path.unlink(missing_ok=True)
        self.held = False
