"""task=eval_classifier: score a trained classifier on a labelled folder it never saw.

    python run.py task=eval_classifier dataset.root=PATH [classifier.checkpoint=PATH/classifier.pt]

Writes the same report as training: report.json (`test_accuracy` on this folder,
`val_accuracy` recorded in the checkpoint at training time, `per_sensor`, `confusion`, and
`gated` when the folder has `_backgrounds/`), confusion.png and per_sensor.png. The
scoring is perception/classifier/held_out.py; this module only wires the config to it.
"""

from __future__ import annotations

from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.held_out import evaluate_on_folder
from neuralfeels_sem.tasks.runner import output_dir


def run(cfg: DictConfig) -> dict:
    classifier = instantiate(cfg.classifier)
    if not isinstance(classifier, MaterialClassifier):
        raise ConfigError(
            "task=eval_classifier evaluates classifier=efficientnet_b0, not the configured classifier"
        )
    data = cfg.dataset
    return evaluate_on_folder(
        classifier, data.root, tuple(data.extensions), int(cfg.task.batch_size), output_dir()
    )
