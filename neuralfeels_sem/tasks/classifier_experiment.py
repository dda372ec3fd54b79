"""task=classifier_experiment: collect, train and evaluate the classifier in one job (figure 3).

    python run.py experiment=classifier

Steps, each in its own sub-directory of the job: `collect/` (a sim training set into
`data/train`), `train/` (task=train_classifier: classifier.pt, report.json with the 15%
test split, confusion.png, per_sensor.png), `heldout/` (a second set rendered with another
seed, never seen in training) and `heldout_eval/` (task=eval_classifier on it). The job's
report.json is the training report plus `heldout_accuracy` and `heldout_per_sensor`, so a
sweep aggregates both.
"""

from __future__ import annotations

import json
import logging

from hydra import compose
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from neuralfeels_sem.tasks import collect_tactile, eval_classifier, train_classifier
from neuralfeels_sem.tasks.runner import output_dir, redirect_output

log = logging.getLogger(__name__)

# Offset between the training and held-out collection seeds, so no contact is rendered twice.
HELDOUT_SEED_OFFSET = 100_000


def _step_config(task: str, overrides: list[str]) -> DictConfig:
    """The full config of one step: the job's own overrides, the step's task, then `overrides`."""
    job_overrides = [
        o
        for o in HydraConfig.get().overrides.task
        if not o.startswith(("task", "experiment", "hydra"))
    ]
    return compose(config_name="config", overrides=[*job_overrides, f"task={task}", *overrides])


def run(cfg: DictConfig) -> dict:
    out = output_dir()
    params = cfg.task
    train_root, heldout_root = out / "data" / "train", out / "data" / "heldout"
    seed = int(cfg.seed)
    size = [f"classifier.input_size={params.input_size}"]
    steps = [
        (
            "collect",
            "collect_tactile",
            collect_tactile.run,
            [
                f"dataset.root={train_root}",
                f"task.samples_per_class_per_sensor={params.samples_per_class_per_sensor}",
                f"seed={seed}",
            ],
        ),
        (
            "train",
            "train_classifier",
            train_classifier.run,
            [
                f"dataset.root={train_root}",
                f"task.max_epochs={params.max_epochs}",
                f"task.patience={params.patience}",
                *size,
            ],
        ),
        (
            "heldout",
            "collect_tactile",
            collect_tactile.run,
            [
                f"dataset.root={heldout_root}",
                f"task.samples_per_class_per_sensor={params.heldout_per_class_per_sensor}",
                f"seed={seed + HELDOUT_SEED_OFFSET}",
            ],
        ),
        (
            "heldout_eval",
            "eval_classifier",
            eval_classifier.run,
            [
                f"dataset.root={heldout_root}",
                f"classifier.checkpoint={out / 'train' / 'classifier.pt'}",
            ],
        ),
    ]
    results = {}
    for step, task, fn, overrides in steps:
        log.info("step %s: task=%s", step, task)
        with redirect_output(out / step):
            results[step] = fn(_step_config(task, overrides))
    report = dict(results["train"])
    report["heldout_accuracy"] = results["heldout_eval"]["test_accuracy"]
    report["heldout_per_sensor"] = results["heldout_eval"]["per_sensor"]
    (out / "report.json").write_text(json.dumps(report, indent=2, default=str))
    log.info("test %.4f, held-out %.4f", report["test_accuracy"], report["heldout_accuracy"])
    return report
