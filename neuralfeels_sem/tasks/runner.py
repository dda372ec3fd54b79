"""Validate the composed config, seed, run the task, and turn user errors into one line.

Single runs exit with code 2 on a UserError (no traceback). In a sweep the error is
written to the job's directory as `error.txt` and the sweep goes on; the aggregate at
the end counts and reports failed jobs. SIGINT and SIGTERM end a run with exit code
130 / 143 and one line on stderr saying what was kept and where (a mapping run writes its
outputs first: pipeline/interrupts.py).
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import NoReturn

from hydra.core.hydra_config import HydraConfig
from hydra.errors import InstantiationException
from hydra.types import RunMode
from hydra.utils import get_method
from omegaconf import DictConfig

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import UserError
from neuralfeels_sem.pipeline.interrupts import Interrupted
from neuralfeels_sem.tasks.preflight import preflight
from neuralfeels_sem.utils.device import THREADS_AUTO, set_threads
from neuralfeels_sem.utils.seed import seed_everything

log = logging.getLogger(__name__)


_output_override: ContextVar[Path | None] = ContextVar("output_override", default=None)


def output_dir() -> Path:
    """The current run's directory (Hydra's), or the working directory outside Hydra.

    A pipeline task running other tasks as steps points each at its own sub-directory
    with `redirect_output`.
    """
    override = _output_override.get()
    if override is not None:
        return override
    try:
        return Path(HydraConfig.get().runtime.output_dir)
    except ValueError:
        return Path.cwd()


@contextmanager
def redirect_output(path: Path) -> Iterator[Path]:
    """Make output_dir() return `path` (created) inside the block."""
    path.mkdir(parents=True, exist_ok=True)
    token = _output_override.set(path)
    try:
        yield path
    finally:
        _output_override.reset(token)


def _is_multirun() -> bool:
    try:
        return HydraConfig.get().mode == RunMode.MULTIRUN
    except ValueError:
        return False


def _terminate(signum: int, _frame) -> None:
    """SIGTERM outside a mapping loop: stop like Ctrl-C does (Python's default is silent)."""
    raise Interrupted(signum, f"terminated (SIGTERM); outputs written so far are in {output_dir()}")


def _on_signals() -> None:
    """Ctrl-C raises KeyboardInterrupt again (run.py's start-up handler ends here); SIGTERM
    raises Interrupted."""
    with contextlib.suppress(ValueError):  # not the main thread (a sweep worker): the default
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, _terminate)


def _close_progress_bars() -> None:
    """End any progress bar a failing loop left open, so the error gets a line of its own."""
    from tqdm import tqdm

    for bar in list(getattr(tqdm, "_instances", ())):
        bar.close()


def _interruption_behind(exc: BaseException) -> BaseException | None:
    """The KeyboardInterrupt or Interrupted that caused `exc` (through its chain), if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, (KeyboardInterrupt, Interrupted)):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _end_interrupted(exc: BaseException) -> NoReturn:
    """One line and the signal's exit code (130 for Ctrl-C)."""
    if isinstance(exc, Interrupted):
        log.debug("interrupted: %s", exc)
        print(exc, file=sys.stderr)
        sys.exit(exc.exit_code)
    print(f"interrupted (SIGINT); outputs written so far are in {output_dir()}", file=sys.stderr)
    sys.exit(130)


def run_task(cfg: DictConfig) -> float | None:
    _on_signals()
    try:
        try:
            validate_config(cfg)
            if _is_multirun():  # a single run was checked by tasks/run_guard.py already
                preflight(cfg)
            seed_everything(int(cfg.seed))
            set_threads(cfg.get("threads", THREADS_AUTO))
            task = get_method(cfg.task._target_)
            result = task(cfg)
        except InstantiationException as exc:
            # Hydra wraps what a constructor raises; a user error inside keeps its one line.
            if isinstance(exc.__cause__, (UserError, Interrupted)):
                raise exc.__cause__ from None
            raise
    except UserError as exc:
        # Hydra's console handler also writes to stderr: log to the run's log file only.
        log.debug("%s: %s", type(exc).__name__, exc)
        if _is_multirun():
            (output_dir() / "error.txt").write_text(f"{type(exc).__name__}: {exc}\n")
            return None
        _close_progress_bars()
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(exc.exit_code)
    except (Interrupted, KeyboardInterrupt) as exc:
        _end_interrupted(exc)
    except Exception as exc:
        # A signal inside a lazy import (mujoco's, pyrender's) surfaces as the ImportError
        # it caused: still an interruption, not a failure.
        interruption = _interruption_behind(exc)
        if interruption is None:
            raise
        _end_interrupted(interruption)
    objective = cfg.task.get("objective") if hasattr(cfg.task, "get") else None
    if objective and isinstance(result, dict) and objective in result:
        return float(result[objective])
    return None
