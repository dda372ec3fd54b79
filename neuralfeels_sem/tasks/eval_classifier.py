"""task=eval_classifier: score a trained classifier on a labelled folder it never saw.

    python run.py task=eval_classifier dataset.root=PATH [classifier.checkpoint=PATH/classifier.pt]

Every image in the folder is test data. Writes the same report as training: report.json
(`test_accuracy` on this folder, `val_accuracy` recorded in the checkpoint at training
time, `per_sensor`, `confusion`), confusion.png and per_sensor.png. Classes absent from the
folder are allowed (with a warning); classes unknown to the checkpoint are an error.
"""

from __future__ import annotations

import logging

from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.errors import ConfigError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.dataset import (
    load_backgrounds,
    load_samples,
    resolve_path,
    scan_dataset,
)
from neuralfeels_sem.perception.classifier.evaluate import (
    predict_in_batches,
    test_report,
    write_report,
)
from neuralfeels_sem.tasks.runner import output_dir

log = logging.getLogger(__name__)


def run(cfg: DictConfig) -> dict:
    classifier = instantiate(cfg.classifier)
    if not isinstance(classifier, MaterialClassifier):
        raise ConfigError(
            "task=eval_classifier evaluates classifier=efficientnet_b0, not the configured classifier"
        )
    ckpt = classifier.loaded  # raises ConfigError when its classes differ from materials
    data = cfg.dataset
    samples = scan_dataset(
        data.root,
        classifier.class_names,
        require_all_classes=False,
        extensions=tuple(data.extensions),
    )
    crop_px = ckpt.meta.get("crop_px")
    loaded = load_samples(
        samples,
        ckpt.input_size,
        crop_px=crop_px,
        backgrounds=load_backgrounds(data.root) if crop_px else None,
    )
    pred = predict_in_batches(classifier.predict_images, loaded.images, int(cfg.task.batch_size))
    report = test_report(loaded.labels, pred, loaded.sensors, classifier.class_names)
    report["val_accuracy"] = ckpt.meta.get("val_accuracy")
    report["checkpoint"] = str(classifier.checkpoint_path)
    report["data"] = {
        "root": str(resolve_path(data.root)),
        "images": len(loaded.labels),
        "skipped_unreadable": loaded.skipped_unreadable,
        "skipped_files": loaded.skipped_files,
        "resized_wrong_size": loaded.resized_wrong_size,
    }
    write_report(report, output_dir(), "evaluation")
    log.info(
        "accuracy %.4f on %d images, per sensor %s; wrote %s",
        report["test_accuracy"],
        len(pred),
        {k: round(v, 4) for k, v in report["per_sensor"].items()},
        output_dir(),
    )
    return report
