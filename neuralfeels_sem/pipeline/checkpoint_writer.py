"""Checkpoint writes off the mapper's path.

The mapper's thread copies the state it must keep (mapping/checkpoint.take_checkpoint, a
fraction of a second); a worker thread packs the hash tables and writes the file (about a
second on the default field, over ten at the paper's 2^24 table). One copy is in flight at
a time, so memory holds at most one extra copy of the state: a checkpoint due while a write
runs is taken at the first frame after it ends (`due`), and one taken regardless waits for
it. A write that fails is raised on the mapper's thread at the next call.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path

from neuralfeels_sem.mapping.checkpoint import write_checkpoint
from neuralfeels_sem.utils.thread_priority import at_priority


class CheckpointWriter:
    """Writes `take_checkpoint` copies to one path, in order, on a worker thread."""

    def __init__(self, path: Path, nice: int = 0) -> None:
        self.path = path  # nice: added to the worker's nice value (utils/thread_priority.py)
        self._jobs: queue.Queue = queue.Queue(maxsize=1)
        self._error: BaseException | None = None
        self._due = False  # a checkpoint's frame passed while a write ran (`due`)
        work = at_priority(self._work, nice)
        self._thread = threading.Thread(target=work, name="checkpoint-writer", daemon=True)
        self._thread.start()

    def submit(self, taken: dict) -> None:
        """Queue `taken` for writing (call `wait` before taking it: one copy in flight)."""
        self._raise()
        self._due = False
        self._jobs.put(taken)

    @property
    def busy(self) -> bool:
        """A submitted checkpoint is not on disk yet."""
        return self._jobs.unfinished_tasks > 0

    def due(self, reached: bool) -> bool:
        """Whether to take a checkpoint now: a checkpoint's frame is `reached` now or was
        since the last submit, and no write is running. At a large table a write can outlast
        the frames between two checkpoints; the next one then waits, not the mapper."""
        self._due = self._due or reached
        return self._due and not self.busy

    def wait(self) -> None:
        """Block until every submitted checkpoint is on disk; raise a failed write's error."""
        self._jobs.join()
        self._raise()

    def close(self) -> None:
        """Finish the queued writes and stop the worker (raises a failed write's error)."""
        self._jobs.put(None)
        self._thread.join()
        self._raise()

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _work(self) -> None:
        while (taken := self._jobs.get()) is not None:
            try:
                if self._error is None:  # after a failure, later writes are not attempted
                    write_checkpoint(self.path, taken)
            except BaseException as exc:  # noqa: BLE001 - raised on the mapper's side
                self._error = exc
            finally:
                self._jobs.task_done()
        self._jobs.task_done()
