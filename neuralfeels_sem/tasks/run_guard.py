"""Hydra callback guarding a run's inputs and a task=map run's directory, run before Hydra
writes into it.

Within seconds of start, before the simulator or the classifier is built:
- for every task, the config's ranges and keys and the files it names
  (configs.validate_config, tasks/preflight.py);
- `mapping.resume` must name a readable checkpoint of the same object (name and content
  hash), sensor, classes and model as this run (mapping/provenance.py);
- the run directory must be new, empty or hold only a start that failed before any result
  (Hydra's config and log), unless the run resumes the checkpoint that directory holds
  (then it continues there: the default run directory of a resumed run is the checkpoint's,
  the `resume_run_dir` resolver in conf/hydra/default.yaml);
- no other live process may be running in it (run.lock with the owner's pid; the lock of
  a process that no longer runs is taken over with a warning).
A refusal prints one line on stderr and exits with code 2, leaving the directory as it was.
"""

from __future__ import annotations

import atexit
import copy
import sys
from pathlib import Path
from typing import Any

from hydra.errors import InstantiationException
from hydra.experimental.callback import Callback
from hydra.utils import instantiate
from omegaconf import DictConfig, open_dict, read_write

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import ConfigError, UserError
from neuralfeels_sem.mapping.checkpoint import read_provenance
from neuralfeels_sem.mapping.provenance import Provenance, check_provenance, object_hash
from neuralfeels_sem.tasks.build import model_config
from neuralfeels_sem.tasks.preflight import preflight
from neuralfeels_sem.utils.run_lock import LOCK_NAME, RunLock


def run_provenance(cfg: DictConfig, obj) -> Provenance:
    """This run's object, sensor, classes and model, as a checkpoint records them."""
    return Provenance(
        object_name=str(cfg.object.name),
        object_hash=object_hash(obj),
        sensor=str(cfg.sensor.name),
        classes=tuple(cfg.materials),
        model=model_config(cfg),
    )


def check_resume(cfg: DictConfig) -> None:
    """Refuse a `mapping.resume` that is missing, unreadable or of another experiment."""
    resume = cfg.mapping.resume
    if not resume:
        return
    saved = read_provenance(resume)
    try:
        obj = instantiate(cfg.object)
    except InstantiationException as exc:
        if isinstance(exc.__cause__, UserError):
            raise exc.__cause__ from None
        raise
    check_provenance(saved, run_provenance(cfg, obj), str(resume))


# What a run writes before its task starts (Hydra's config and log, the lock): a directory
# holding only these is a start that failed before any result (say, an input the task
# itself refused), and the corrected command may run there.
START_FILES = frozenset({".hydra", "run.log", LOCK_NAME})


def check_run_dir(run_dir: Path, resume: str | None) -> None:
    """Refuse a run directory that is a file or holds another run's results."""
    if run_dir.exists() and not run_dir.is_dir():
        raise ConfigError(f"hydra.run.dir={run_dir} is a file; choose a directory")
    if not run_dir.is_dir():
        return
    resumes_here = bool(resume) and Path(resume).resolve().parent == run_dir.resolve()
    held = sorted(p.name for p in run_dir.iterdir() if p.name not in START_FILES)
    if held and not resumes_here:
        shown = ", ".join(held[:4]) + (", ..." if len(held) > 4 else "")
        checkpoint = run_dir / "checkpoint.pt"
        then = (
            f"or continue that run with mapping.resume={checkpoint}"
            if checkpoint.is_file()
            else "or delete it (it holds no checkpoint to resume)"
        )
        raise ConfigError(
            f"hydra.run.dir={run_dir} already holds a run ({shown}); choose a new directory, {then}"
        )


def lock_run_dir(run_dir: Path) -> RunLock:
    """Create `run_dir` and take its lock for the life of this process."""
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        lock = RunLock(run_dir)
        lock.acquire()
    except PermissionError as exc:
        raise ConfigError(
            f"hydra.run.dir={run_dir} is not writable ({exc.strerror}); choose another directory"
        ) from exc
    atexit.register(lock.release)
    return lock


class RunDirectoryGuard(Callback):
    """Checks of conf/hydra/default.yaml's callbacks for a single task=map run."""

    def __init__(self) -> None:
        self.lock: RunLock | None = None

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        run_dir = Path(str(config.hydra.run.dir))
        task_cfg = copy.deepcopy(config)  # what the task will see: no `hydra` node
        with read_write(task_cfg), open_dict(task_cfg):
            del task_cfg["hydra"]
        try:
            validate_config(task_cfg)
            preflight(task_cfg)  # every task: files named, memory, ignored settings
            if config.task.get("name") != "map":
                return
            check_resume(task_cfg)
            check_run_dir(run_dir, task_cfg.mapping.resume)
            self.lock = lock_run_dir(run_dir)
        except UserError as exc:
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(exc.exit_code)

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        if self.lock is not None:
            self.lock.release()
