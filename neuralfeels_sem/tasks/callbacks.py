"""Hydra callbacks (conf/hydra/default.yaml): not a task.

SweepAggregator sits above eval and viz, so that eval (the summary) never imports viz
(the experiment's plots).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from neuralfeels_sem.eval.aggregate import headline_table, summarize

log = logging.getLogger(__name__)


class SweepAggregator(Callback):
    """Hydra callback: summarize the sweep directory when a multirun ends."""

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        if not sweep_dir.is_dir():
            return
        summary = summarize(sweep_dir)
        log.info(
            "sweep summary: %s (%d groups)", sweep_dir / "summary.json", len(summary["groups"])
        )
        table = headline_table(summary)
        if table:
            log.info("mean ± std per setting:\n%s", table)
        if summary["failed"]:
            log.error(
                "%d of %d jobs failed: %s",
                len(summary["failed"]),
                len(summary["jobs"]),
                summary["failed"],
            )
        try:
            from neuralfeels_sem.viz.sweep_plots import plot_experiment
        except ImportError:
            return
        plot_experiment(summary, sweep_dir)
