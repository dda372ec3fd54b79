"""Score a trained classifier on a labelled folder it never saw (task=eval_classifier).

Every image in the folder is test data. The report is the training report's form:
`test_accuracy` on this folder, `val_accuracy` recorded in the checkpoint at training
time, `per_sensor`, `confusion`. Classes absent from the folder are allowed (with a
warning); classes unknown to the checkpoint are an error. With `_backgrounds/<sensor>.png`
in the folder, `gated` adds the accuracy on the touches the mapper would label (confident
enough, not cut off by the sensor edge) and their share.
"""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.perception.classifier.dataset import (
    data_summary,
    load_backgrounds,
    load_samples,
    press_groups,
    scan_dataset,
)
from neuralfeels_sem.perception.classifier.evaluate import (
    gated_report,
    per_press_kind,
    predict_probs_in_batches,
    test_report,
    write_report,
)
from neuralfeels_sem.perception.classifier.infer import MaterialClassifier
from neuralfeels_sem.perception.contact import edge_share

log = logging.getLogger(__name__)


def evaluate_on_folder(
    classifier: MaterialClassifier,
    root: str,
    extensions: tuple[str, ...],
    batch_size: int,
    out_dir: Path,
) -> dict:
    """Classify every image under `root`; writes report.json and its pictures into `out_dir`."""
    ckpt = classifier.loaded  # raises ConfigError when its classes differ from materials
    samples = scan_dataset(
        root, classifier.class_names, require_all_classes=False, extensions=tuple(extensions)
    )
    crop_px = ckpt.meta.get("crop_px")
    backgrounds = load_backgrounds(root)
    loaded = load_samples(
        samples, ckpt.input_size, crop_px=crop_px, backgrounds=backgrounds if crop_px else None
    )
    probs = predict_probs_in_batches(classifier.predict_images, loaded.images, int(batch_size))
    pred = probs.argmax(1) if len(probs) else np.zeros(0, dtype=np.int64)
    report = test_report(loaded.labels, pred, loaded.sensors, classifier.class_names)
    if backgrounds and set(loaded.sensors) <= set(backgrounds):
        shares = _edge_shares(classifier, loaded.paths, loaded.sensors, backgrounds)
        report["gated"] = gated_report(
            loaded.labels, probs, shares, classifier.min_confidence, classifier.max_edge_share
        )
    for key, groups in press_groups(root, loaded.paths).items():
        report[key] = per_press_kind(loaded.labels, pred, groups)
    report["val_accuracy"] = ckpt.meta.get("val_accuracy")
    report["checkpoint"] = str(classifier.checkpoint_path)
    report["data"] = data_summary(root, loaded)
    write_report(report, out_dir, "evaluation")
    _log(report, len(pred), out_dir)
    return report


def _log(report: dict, images: int, out_dir: Path) -> None:
    if "gated" in report:
        gated = report["gated"]
        log.info(
            "gated (min_confidence %.2f, max_edge_share %.2f): %d of %d labelled (%.1f %%), "
            "%.4f correct",
            gated["min_confidence"],
            gated["max_edge_share"],
            gated["kept_count"],
            images,
            100 * gated["kept_share"],
            gated["accuracy_kept"] or 0.0,
        )
    log.info(
        "accuracy %.4f on %d images, per sensor %s; wrote %s",
        report["test_accuracy"],
        images,
        {k: round(v, 4) for k, v in report["per_sensor"].items()},
        out_dir,
    )


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
