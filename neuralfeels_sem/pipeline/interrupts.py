"""SIGINT (Ctrl-C) and SIGTERM during a mapping run: finish the frame, write, exit 130 / 143.

Inside `StopOnSignal` the first signal only asks the frame loop to stop after the frame
in progress, so the checkpoint and the partial outputs hold every frame the run has seen;
a second signal stops at once (Interrupted), keeping what was written before.
"""

from __future__ import annotations

import logging
import signal
from pathlib import Path

log = logging.getLogger(__name__)

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(Exception):
    """A run stopped by a signal after writing its outputs; the process exits 128 + signum."""

    def __init__(self, signum: int, message: str) -> None:
        super().__init__(message)
        self.signum = signum
        self.exit_code = 128 + signum


class StopOnSignal:
    """Context manager: `signum` is the first SIGINT / SIGTERM received inside it, or None."""

    def __init__(self, run_dir: Path) -> None:
        self.run_dir = run_dir
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    @property
    def requested(self) -> bool:
        return self.signum is not None

    def _handle(self, signum: int, _frame) -> None:
        if self.signum is not None:  # the second signal: stop now
            raise Interrupted(
                signum,
                f"stopped at once by a second {signal.Signals(signum).name}; the last checkpoint "
                f"written is {self.run_dir / 'checkpoint.pt'}",
            )
        self.signum = signum
        log.warning(
            "%s: finishing the frame in progress, then writing the outputs (send it again to stop at once)",
            signal.Signals(signum).name,
        )

    def __enter__(self) -> StopOnSignal:
        try:
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
        except ValueError:  # not the main thread (a sweep worker): keep the default handling
            self._restore()
        return self

    def __exit__(self, *exc) -> None:
        self._restore()

    def _restore(self) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()
