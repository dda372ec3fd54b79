"""A training run of the tactile material classifier, from an image folder to classifier.pt.

Scans `<root>/<sensor>/<material>/<id>.png`, caps and splits it (stratified by sensor and
class), trains with `fit.fit` (resumable from last.pt), scores the best epoch on the
validation and test sets and exports it. Fine-tuning (finetune.py) starts from a trained
checkpoint instead of a new model and may mix a second set (`sim_root`, all of it used for
training only) into every epoch by `real_ratio`; validation and test stay on `root`. Writes into `run_dir`: classifier.pt (weights,
class names, input size, normalisation), report.json (test_accuracy, val_accuracy,
per_sensor, confusion, ...), confusion.png, per_sensor.png, split.json (which file went
where), history.json, best.pt and last.pt.
"""

from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.perception.classifier.checkpoint import (
    ClassifierCheckpoint,
    load_checkpoint,
    save_checkpoint,
)
from neuralfeels_sem.perception.classifier.dataset import (
    LoadedSet,
    Sample,
    class_counts,
    data_summary,
    load_backgrounds,
    load_samples,
    press_groups,
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
from neuralfeels_sem.perception.classifier.finetune import MixedDraw, initial_checkpoint
from neuralfeels_sem.perception.classifier.fit import BEST, LAST, TrainResult, TrainSettings, fit
from neuralfeels_sem.perception.classifier.infer import MaterialClassifier
from neuralfeels_sem.perception.classifier.predict import predict_probs
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD
from neuralfeels_sem.utils.device import resolve_device

log = logging.getLogger(__name__)


@dataclass
class DataSettings:
    """Which images to train on (the dataset config group)."""

    root: str
    extensions: tuple[str, ...]
    max_per_group: int | None = None
    split: tuple[float, float, float] = (0.7, 0.15, 0.15)  # train, val, test
    sim_root: str | None = None  # a second set mixed into training (finetune.MixedDraw)
    real_ratio: float = 0.5  # share of `root` images in each epoch when sim_root is set


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
    """last.pt to continue from: `auto` (the run dir's, if any), `never`, or a path."""
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


def train_classifier(
    classifier: MaterialClassifier,
    data: DataSettings,
    settings: TrainSettings,
    run_dir: Path,
    device_name: str = "auto",
    resume: str = "auto",
    export_fp16: bool = False,
    init_from: str | None = None,
) -> dict:
    """Train `classifier`'s model on `data` (seeded by settings.seed); returns the report.
    `init_from` (`shipped` or a classifier.pt) fine-tunes that model at its size and crop."""
    class_names = list(classifier.class_names)
    init = initial_checkpoint(init_from, class_names) if init_from else None
    size, crop_px = _input_of(classifier, init)
    loaded, parts = _load_and_split(data, class_names, size, crop_px, settings.seed, run_dir)
    train_x, train_y, draw, mix = _training_set(
        loaded, parts["train"], data, class_names, size, crop_px, settings.seed
    )
    device = _device(device_name)
    mean, std = list(IMAGENET_MEAN), list(IMAGENET_STD)
    va = parts["val"]
    result = fit(
        init.build(device) if init is not None else classifier.new_model(),
        train_x,
        train_y,
        loaded.images[va],
        loaded.labels[va],
        settings,
        run_dir,
        class_names,
        size,
        mean,
        std,
        device,
        resume_path(resume, run_dir),
        checkpoint_meta={"crop_px": crop_px},
        draw=draw,
    )
    model = load_checkpoint(run_dir / BEST).build(device)

    def predict(batch: np.ndarray) -> np.ndarray:
        return predict_probs(model, batch, mean, std, device)

    report = _report(predict, loaded, parts, data.root, class_names)
    report["training"] = {
        **asdict(settings),
        **{"input_size": size, "crop_px": crop_px, "device": str(device)},
        **{"weights": classifier.weights, "init_from": init_from, "mix": mix},
        **_outcome(result),
    }
    meta = {"crop_px": crop_px, "data_root": report["data"]["root"]}
    for key in ("val_accuracy", "test_accuracy", "per_sensor", "training"):
        meta[key] = report[key]
    save_checkpoint(
        run_dir / "classifier.pt", model, class_names, size, mean, std, meta=meta, fp16=export_fp16
    )
    _write(report, run_dir)
    return report


def _write(report: dict, run_dir: Path) -> None:
    write_report(report, run_dir, "test set")
    log.info(
        "test accuracy %.4f, val accuracy %.4f, per sensor %s; wrote %s",
        report["test_accuracy"],
        report["val_accuracy"],
        {k: round(v, 4) for k, v in report["per_sensor"].items()},
        run_dir,
    )


def _load_and_split(
    data: DataSettings, class_names: list[str], size: int, crop_px: int, seed: int, run_dir: Path
) -> tuple[LoadedSet, dict[str, np.ndarray]]:
    """Scan, cap, load and split the images; writes split.json."""
    # A mixed-in set may supply the classes not recorded on one's own sensors.
    samples = scan_dataset(
        data.root,
        class_names,
        require_all_classes=data.sim_root is None,
        extensions=tuple(data.extensions),
    )
    samples = cap_per_group(samples, data.max_per_group, seed)
    loaded = load_samples(
        samples, size, crop_px=crop_px, backgrounds=load_backgrounds(data.root) if crop_px else None
    )
    parts = stratified_split(loaded.labels, loaded.sensors, tuple(data.split), seed)
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
    return loaded, parts


def _input_of(classifier: MaterialClassifier, init: ClassifierCheckpoint | None) -> tuple:
    """(input size, crop) to train at: the classifier config's, or a fine-tuned model's own."""
    if init is None:
        return classifier.input_size, classifier.crop_px
    if init.input_size != classifier.input_size:
        log.info(
            "fine-tuning at the checkpoint's input size %d (classifier.input_size=%d is ignored)",
            init.input_size,
            classifier.input_size,
        )
    return init.input_size, init.meta.get("crop_px")


def _training_set(
    loaded: LoadedSet,
    train: np.ndarray,
    data: DataSettings,
    class_names: list[str],
    size: int,
    crop_px: int | None,
    seed: int,
) -> tuple[np.ndarray, np.ndarray, MixedDraw | None, dict | None]:
    """Training images and labels ([real; sim] when data.sim_root is set), the epoch draw
    and the report's `mix` entry."""
    real_x, real_y = loaded.images[train], loaded.labels[train]
    if data.sim_root is None:
        return real_x, real_y, None, None
    samples = scan_dataset(
        data.sim_root, class_names, require_all_classes=False, extensions=tuple(data.extensions)
    )
    samples = cap_per_group(samples, data.max_per_group, seed)
    backgrounds = load_backgrounds(data.sim_root) if crop_px else None
    sim = load_samples(samples, size, "loading sim images", crop_px, backgrounds)
    missing = sorted(set(range(len(class_names))) - set(real_y.tolist()) - set(sim.labels.tolist()))
    if missing:
        raise DataError(
            f"no training image of {[class_names[c] for c in missing]} in dataset.root or "
            "dataset.sim_root: collect them or set materials to the classes present"
        )
    draw = MixedDraw(len(real_y), len(sim.labels), float(data.real_ratio))
    mix = {
        "sim_root": str(resolve_path(data.sim_root)),
        "sim_images": len(sim.labels),
        "real_train_images": len(real_y),
        "real_ratio": float(data.real_ratio),
        "sim_per_epoch": draw.extra_per_epoch,
    }
    log.info("mixing %d sim images into %d real ones per epoch", draw.extra_per_epoch, len(real_y))
    images = np.concatenate([real_x, sim.images])
    return images, np.concatenate([real_y, sim.labels]), draw, mix


def _device(name: str) -> torch.device:
    # CPU threads: the root key `threads`, set once at start-up (utils/device.py).
    return resolve_device(name)


def _report(predict, loaded: LoadedSet, parts: dict, data_root: str, class_names) -> dict:
    """Test-set report of the best model, with its validation accuracy and the data counts."""
    va, te = parts["val"], parts["test"]
    val_pred = predict_in_batches(predict, loaded.images[va], 64, "validation")
    test_pred = predict_in_batches(predict, loaded.images[te], 64, "test")
    report = test_report(loaded.labels[te], test_pred, loaded.sensors[te], class_names)
    report["val_accuracy"] = float((val_pred == loaded.labels[va]).mean())
    for key, groups in press_groups(data_root, loaded.paths).items():
        report[key] = per_press_kind(loaded.labels[te], test_pred, groups[te])
    report["counts"] = {"train": len(parts["train"]), "val": len(va), "test": len(te)}
    report["data"] = {
        **data_summary(data_root, loaded),
        "per_sensor_class": class_counts(loaded.labels, loaded.sensors, class_names),
    }
    return report


def _outcome(result: TrainResult) -> dict:
    return {
        "best_epoch": result.best_epoch,
        "epochs_run": result.epochs_run,
        "stopped_early": result.stopped_early,
        "resumed_from_epoch": result.resumed_from_epoch,
    }
