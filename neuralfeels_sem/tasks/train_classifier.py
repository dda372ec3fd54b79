"""task=train_classifier: train the tactile material classifier on a folder of DIGIT images.

    python run.py task=train_classifier dataset.root=PATH [classifier.input_size=224]

Writes into the run directory: classifier.pt (weights, class names, input size,
normalisation), report.json (test_accuracy, val_accuracy, per_sensor, confusion, ...),
confusion.png, per_sensor.png, split.json (which file went where), history.json,
best.pt and last.pt (resume state: rerun with the same hydra.run.dir, or task.resume=DIR).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.perception.classifier.dataset import (
    Sample,
    class_counts,
    load_backgrounds,
    load_samples,
    press_kinds,
    resolve_path,
    scan_dataset,
    stratified_split,
)
from neuralfeels_sem.perception.classifier.evaluate import (
    per_press_kind,
    predict_in_batches,
    test_report,
    write_report,
)
from neuralfeels_sem.perception.classifier.predict import predict_probs
from neuralfeels_sem.perception.classifier.train import BEST, LAST, TrainSettings, train
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD
from neuralfeels_sem.tasks.runner import output_dir
from neuralfeels_sem.utils.device import resolve_device

log = logging.getLogger(__name__)


def cap_per_group(samples: list[Sample], max_per_group: int | None, seed: int) -> list[Sample]:
    """At most max_per_group samples per (sensor, class), chosen with a fixed seed."""
    if max_per_group is None:
        return samples
    rng = np.random.default_rng(seed)
    groups: dict[tuple[str, int], list[Sample]] = {}
    for s in samples:
        groups.setdefault((s.sensor, s.label), []).append(s)
    kept = []
    for key in sorted(groups):
        members = groups[key]
        pick = sorted(rng.permutation(len(members))[:max_per_group])
        kept.extend(members[i] for i in pick)
    return kept


def resume_path(resume: str, run_dir: Path) -> Path | None:
    if resume == "never":
        return None
    if resume == "auto":
        return run_dir / LAST if (run_dir / LAST).is_file() else None
    path = resolve_path(resume)
    path = path / LAST if path.is_dir() else path
    if not path.is_file():
        raise ConfigError(
            f"task.resume={resume}: no {LAST} there; give a run directory of task=train_classifier"
        )
    return path


def run(cfg: DictConfig) -> dict:
    classifier = instantiate(cfg.classifier)
    if not isinstance(classifier, MaterialClassifier):
        raise ConfigError(
            "task=train_classifier trains classifier=efficientnet_b0, not the configured classifier"
        )
    class_names = list(classifier.class_names)
    size = classifier.input_size
    task, data = cfg.task, cfg.dataset
    run_dir = output_dir()
    seed = int(cfg.seed)

    samples = scan_dataset(
        data.root, class_names, require_all_classes=True, extensions=tuple(data.extensions)
    )
    samples = cap_per_group(samples, data.max_per_group, seed)
    crop_px = classifier.crop_px
    loaded = load_samples(
        samples, size, crop_px=crop_px, backgrounds=load_backgrounds(data.root) if crop_px else None
    )
    parts = stratified_split(loaded.labels, loaded.sensors, tuple(task.split), seed)
    for name in ("train", "val", "test"):
        if len(parts[name]) == 0:
            raise DataError(
                f"the {name} split of dataset.root={data.root} is empty; collect more images"
            )
    log.info(
        "images: %d train, %d val, %d test at %dx%d",
        *(len(parts[k]) for k in ("train", "val", "test")),
        size,
        size,
    )
    root = resolve_path(data.root)
    (run_dir / "split.json").write_text(
        json.dumps(
            {
                k: [str(Path(loaded.paths[i]).relative_to(root)) for i in v]
                for k, v in parts.items()
            },
            indent=1,
        )
    )

    device = resolve_device(cfg.classifier.device)
    if device.type == "cpu" and os.environ.get("OMP_NUM_THREADS", "").isdigit():
        # All cores by default; an explicit OMP_NUM_THREADS wins (a shared, busy machine
        # trains faster on fewer threads than on oversubscribed ones).
        torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))
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
        seed=seed,
        lr_schedule=task.lr_schedule,
        min_lr_ratio=task.min_lr_ratio,
    )
    mean, std = list(IMAGENET_MEAN), list(IMAGENET_STD)
    tr, va, te = parts["train"], parts["val"], parts["test"]
    result = train(
        classifier.new_model(),
        loaded.images[tr],
        loaded.labels[tr],
        loaded.images[va],
        loaded.labels[va],
        settings,
        run_dir,
        class_names,
        size,
        mean,
        std,
        device,
        resume_path(task.resume, run_dir),
        checkpoint_meta={"crop_px": crop_px},
    )

    best = load_checkpoint(run_dir / BEST)
    model = best.build(device)

    def predict(batch: np.ndarray) -> np.ndarray:
        return predict_probs(model, batch, mean, std, device)

    val_pred = predict_in_batches(predict, loaded.images[va], 64, "validation")
    test_pred = predict_in_batches(predict, loaded.images[te], 64, "test")
    report = test_report(loaded.labels[te], test_pred, loaded.sensors[te], class_names)
    report["val_accuracy"] = float((val_pred == loaded.labels[va]).mean())
    kinds = press_kinds(data.root, loaded.paths)
    if kinds is not None:
        report["per_press_kind"] = per_press_kind(loaded.labels[te], test_pred, kinds[te])
    report["counts"] = {"train": len(tr), "val": len(va), "test": len(te)}
    report["data"] = {
        "root": str(root),
        "images": len(loaded.labels),
        "skipped_unreadable": loaded.skipped_unreadable,
        "skipped_files": loaded.skipped_files,
        "resized_wrong_size": loaded.resized_wrong_size,
        "per_sensor_class": class_counts(loaded.labels, loaded.sensors, class_names),
    }
    report["training"] = {
        **asdict(settings),
        "input_size": size,
        "crop_px": crop_px,
        "device": str(device),
        "weights": classifier.weights,
        "best_epoch": result.best_epoch,
        "epochs_run": result.epochs_run,
        "stopped_early": result.stopped_early,
        "resumed_from_epoch": result.resumed_from_epoch,
    }
    meta = {
        "crop_px": crop_px,
        "val_accuracy": report["val_accuracy"],
        "test_accuracy": report["test_accuracy"],
        "per_sensor": report["per_sensor"],
        "data_root": str(root),
        "training": report["training"],
    }
    save_checkpoint(
        run_dir / "classifier.pt",
        model,
        class_names,
        size,
        mean,
        std,
        meta=meta,
        fp16=task.export_fp16,
    )
    write_report(report, run_dir, "test set")
    log.info(
        "test accuracy %.4f, val accuracy %.4f, per sensor %s; wrote %s",
        report["test_accuracy"],
        report["val_accuracy"],
        {k: round(v, 4) for k, v in report["per_sensor"].items()},
        run_dir,
    )
    return report
