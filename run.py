"""SemanticFeels entry point: compose the config tree, then run the chosen task.

python run.py sensor=sim object=plushie          # default task: map
python run.py task=train_classifier dataset.root=PATH
python run.py -m experiment=multi_material launcher=joblib
"""

import os
import signal
import sys

_imports_done = False


def _stopped_during_start_up(signum: int, _frame) -> None:
    # Until the task runs (tasks/runner.py takes over), a signal ends the start-up in one
    # line instead of a traceback from whichever import it interrupted.
    print(
        f"interrupted ({signal.Signals(signum).name}) during start-up; nothing was mapped",
        file=sys.stderr,
        flush=True,
    )
    if not _imports_done:  # an import may catch SystemExit (a bare except): leave at once
        os._exit(128 + signum)
    sys.exit(128 + signum)


signal.signal(signal.SIGINT, _stopped_during_start_up)
signal.signal(signal.SIGTERM, _stopped_during_start_up)

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

import neuralfeels_sem  # noqa: E402, F401  (sets headless rendering defaults before any GL import)
from neuralfeels_sem.configs import register_configs  # noqa: E402
from neuralfeels_sem.tasks import cli_errors  # noqa: E402

register_configs()
cli_errors.install()  # a typo Hydra catches while composing: one line, exit 2
_imports_done = True


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float | None:
    from neuralfeels_sem.tasks.runner import run_task

    return run_task(cfg)


if __name__ == "__main__":
    main()
