"""task=eval_classifier: score a trained classifier on a labelled folder it never saw.

    python run.py task=eval_classifier dataset.root=PATH [classifier.checkpoint=PATH/classifier.pt]

Every image in the folder is test data. Writes the same report as training: report.json
(`test_accuracy` on this folder, `val_accuracy` recorded in the checkpoint at training
time, `per_sensor`, `confusion`), confusion.png and per_sensor.png. Classes absent from the
folder are allowed (with a warning); classes unknown to the checkpoint are an error.
With `_backgrounds/<sensor>.png` in the folder, `gated` adds the accuracy on the touches
the mapper would label (confident enough, not cut off by the sensor edge) and their share.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np
from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.dataset import (
    load_backgrounds,
    load_samples,
    press_kinds,
    resolve_path,
    scan_dataset,
)
from neuralfeels_sem.perception.classifier.evaluate import (
    gated_report,
    per_press_kind,
    predict_probs_in_batches,
    test_report,
    write_report,
)
from neuralfeels_sem.perception.contact import edge_share
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
    backgrounds = load_backgrounds(data.root)
    loaded = load_samples(
        samples,
        ckpt.input_size,
        crop_px=crop_px,
        backgrounds=backgrounds if crop_px else None,
    )
    probs = predict_probs_in_batches(
        classifier.predict_images, loaded.images, int(cfg.task.batch_size)
    )
    pred = probs.argmax(1) if len(probs) else np.zeros(0, dtype=np.int64)
    report = test_report(loaded.labels, pred, loaded.sensors, classifier.class_names)
    if backgrounds and set(loaded.sensors) <= set(backgrounds):
        shares = _edge_shares(classifier, loaded.paths, loaded.sensors, backgrounds)
        report["gated"] = gated_report(
            loaded.labels, probs, shares, classifier.min_confidence, classifier.max_edge_share
        )
    kinds = press_kinds(data.root, loaded.paths)
    if kinds is not None:
        report["per_press_kind"] = per_press_kind(loaded.labels, pred, kinds)
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
    if "gated" in report:
        gated = report["gated"]
        log.info(
            "gated (min_confidence %.2f, max_edge_share %.2f): %d of %d labelled (%.1f %%), "
            "%.4f correct",
            gated["min_confidence"],
            gated["max_edge_share"],
            gated["kept_count"],
            len(pred),
            100 * gated["kept_share"],
            gated["accuracy_kept"] or 0.0,
        )
    log.info(
        "accuracy %.4f on %d images, per sensor %s; wrote %s",
        report["test_accuracy"],
        len(pred),
        {k: round(v, 4) for k, v in report["per_sensor"].items()},
        output_dir(),
    )
    return report


def _edge_shares(
    classifier: MaterialClassifier,
    paths: list[str],
    sensors: np.ndarray,
    backgrounds: dict[str, np.ndarray],
) -> np.ndarray:
    """Share of each image's contact in the border band, against its sensor's background."""
    shares = np.zeros(len(paths))
    for i, (path, sensor) in enumerate(zip(paths, sensors)):
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        background = backgrounds[sensor]
        if image is None or image.shape != background.shape:
            shares[i] = 0.0  # unreadable images were skipped; resized ones have no border band
            continue
        mask = classifier.gate.mask(np.ascontiguousarray(image[..., ::-1]), background)
        shares[i] = edge_share(mask, classifier.edge_px)
    return shares
