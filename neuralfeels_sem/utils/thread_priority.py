"""Helper threads step back for the mapper (`mapping.helper_nice`).

The mapper's optimiser steps are the loop's critical path: at sensor.pace=offline the
producer waits for room in the queue about a quarter of its time, and the loop's wall time
is the mapper's. On two cores, though, the mapper shares them with the acquisition,
perception, evaluation and checkpoint threads, and the kernel's fair scheduler gives each
runnable thread an equal share, so the mapper ran for two thirds of the loop's wall time
and waited for a core the rest. A helper thread with a higher nice value still runs
whenever a core is free, but yields it to the mapper when both want one (the measurement:
docs/usage.md#pace-offline-and-realtime).

Linux only: there a thread's nice value is its own (setpriority on its thread id); on other
systems the setting changes nothing. The value is added to the thread's current one
(a process started under `nice` keeps its offset), up to 19.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
from collections.abc import Callable

log = logging.getLogger(__name__)

MAX_NICE = 19


def lower_this_thread(nice: int) -> None:
    """Add `nice` to the calling thread's nice value (Linux; 0: leave it)."""
    if nice <= 0 or sys.platform != "linux":
        return
    tid = threading.get_native_id()
    try:
        current = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(MAX_NICE, current + nice))
    except OSError as exc:  # a sandbox that forbids it: the thread runs as before
        log.debug("could not lower thread %s's priority: %s", threading.current_thread().name, exc)


def at_priority(target: Callable[[], None], nice: int) -> Callable[[], None]:
    """`target`, run after lowering its thread's priority by `nice` (a Thread's target)."""

    def run() -> None:
        lower_this_thread(nice)
        target()

    return run
