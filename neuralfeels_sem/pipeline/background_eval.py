"""Scoring passes and progression snapshots off the mapper's path (sensor.pace=realtime).

Both only read the field, so the mapper's side hands over a copy of it, taken between two
optimiser steps (a deep copy: about 0.08 s for the CPU default field, against 0.2-0.4 s
for a scoring pass and 1.9 s for a snapshot, measured on the 2-core CPU at load 9), and
goes on mapping while a worker thread scores the copy and writes the snapshot. Jobs run
one at a time in the order given, so the curves keep their order; at most one waits, so
a mapper faster than its scoring waits for it rather than piling up copies. `drain` waits
for every job (before a checkpoint records the scorer's curves, and at the end); an
exception in the worker is raised there, on the mapper's side.
"""

from __future__ import annotations

import copy
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from torch import nn

from neuralfeels_sem.eval.run_scorer import RunScorer
from neuralfeels_sem.utils.thread_priority import at_priority


@dataclass
class EvalJob:
    field: nn.Module  # a copy: the mapper trains on
    frame_index: int
    time_s: float
    field_T_gt: np.ndarray | None
    score: bool
    snapshot: bool


class BackgroundEval:
    """Runs EvalJobs in a worker: `scorer.score` for the curves, `write_snapshot` for the
    progression snapshots; finished scoring passes wait in `collect()` for the observers."""

    def __init__(
        self,
        scorer: RunScorer,
        write_snapshot: Callable[[nn.Module, np.ndarray | None, float, int], None],
        nice: int = 0,  # added to the worker's nice value (utils/thread_priority.py)
    ) -> None:
        self.scorer = scorer
        self.write_snapshot = write_snapshot
        self._jobs: queue.Queue = queue.Queue(maxsize=1)
        self._done: list[tuple[int, float, dict | None]] = []
        self._lock = threading.Lock()
        self._error: BaseException | None = None
        work = at_priority(self._work, nice)
        self._thread = threading.Thread(target=work, name="background-eval", daemon=True)
        self._thread.start()

    def submit(
        self,
        field: nn.Module,
        frame_index: int,
        time_s: float,
        field_T_gt,
        score: bool,
        snapshot: bool,
    ) -> None:
        """Copy `field` now and queue its scoring and/or snapshot."""
        self._raise()
        job = EvalJob(copy.deepcopy(field), frame_index, time_s, field_T_gt, score, snapshot)
        self._jobs.put(job)

    def collect(self) -> list[tuple[int, float, dict | None]]:
        """The scoring passes finished since the last call: (frame index, time, scores)."""
        self._raise()
        with self._lock:
            done, self._done = self._done, []
        return done

    def drain(self) -> list[tuple[int, float, dict | None]]:
        """Wait for every queued job; the passes not collected yet."""
        self._jobs.join()
        return self.collect()

    def close(self) -> None:
        """Stop the worker after the queued jobs (called once, at the end)."""
        self._jobs.put(None)
        self._thread.join()

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _work(self) -> None:
        while (job := self._jobs.get()) is not None:
            try:
                if self._error is None:
                    self._run(job)
            except BaseException as exc:  # noqa: BLE001 - raised on the mapper's side
                self._error = exc
            finally:
                self._jobs.task_done()
        self._jobs.task_done()

    def _run(self, job: EvalJob) -> None:
        if job.score:
            scores = self.scorer.score(job.field, job.frame_index, job.time_s, job.field_T_gt)
            with self._lock:
                self._done.append((job.frame_index, job.time_s, scores))
        if job.snapshot:
            self.write_snapshot(job.field, job.field_T_gt, job.time_s, job.frame_index)
