"""task=train_classifier: train the tactile material classifier on a folder of DIGIT images.

    python run.py task=train_classifier dataset.root=PATH [classifier.input_size=224]
    python run.py task=train_classifier dataset.root=REAL task.init_from=shipped dataset.sim_root=SIM

Writes into the run directory: classifier.pt (weights, class names, input size,
normalisation), report.json (test_accuracy, val_accuracy, per_sensor, confusion, ...),
confusion.png, per_sensor.png, split.json (which file went where), history.json,
best.pt and last.pt (resume state: rerun with the same hydra.run.dir, or task.resume=DIR).
The run itself is perception/classifier/train.py; this module only wires the config to it.
"""

from __future__ import annotations

from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.fit import TrainSettings
from neuralfeels_sem.perception.classifier.train import DataSettings, train_classifier
from neuralfeels_sem.tasks.runner import output_dir


def run(cfg: DictConfig) -> dict:
    classifier = instantiate(cfg.classifier)
    if not isinstance(classifier, MaterialClassifier):
        raise ConfigError(
            "task=train_classifier trains classifier=efficientnet_b0, not the configured classifier"
        )
    task, data = cfg.task, cfg.dataset
    settings = TrainSettings(
        batch_size=task.batch_size,
        lr=task.lr,
        weight_decay=task.weight_decay,
        max_epochs=task.max_epochs,
        patience=task.patience,
        rotation_deg=task.rotation_deg,
        brightness=task.brightness,
        contrast=task.contrast,
        color_gain=task.color_gain,
        seed=int(cfg.seed),
        lr_schedule=task.lr_schedule,
        min_lr_ratio=task.min_lr_ratio,
    )
    images = DataSettings(
        root=data.root,
        extensions=tuple(data.extensions),
        max_per_group=data.max_per_group,
        split=tuple(task.split),
        sim_root=data.sim_root,
        real_ratio=task.real_ratio,
    )
    return train_classifier(
        classifier,
        images,
        settings,
        output_dir(),
        device_name=cfg.classifier.device,
        resume=task.resume,
        export_fp16=task.export_fp16,
        init_from=task.init_from,
    )
