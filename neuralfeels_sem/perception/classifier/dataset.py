"""Tactile material data sets on disk: `<root>/<sensor>/<material>/<id>.png`.

The layout `task=collect_tactile` writes, and the one a user's own DIGIT recordings
use. Folders whose names start with `_` or `.` (e.g. `_backgrounds`) are not sensors.
Images are loaded once, resized to the model's input size and kept in memory as uint8.
Nothing is dropped silently: unreadable files are skipped with a warning and counted,
images of the wrong size are resized and counted.
"""

from __future__ import annotations

import json
import logging
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.classifier.evaluate import curvature_bin
from neuralfeels_sem.perception.classifier.transforms import preprocess
from neuralfeels_sem.utils.paths import REPO_DIR

log = logging.getLogger(__name__)

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class Sample:
    path: Path
    sensor: str
    label: int


@dataclass
class LoadedSet:
    """Images (N, S, S, 3) uint8 with labels (N,) and sensor names (N,), plus load counts."""

    images: np.ndarray
    labels: np.ndarray
    sensors: np.ndarray
    paths: list[str]
    skipped_unreadable: int = 0
    resized_wrong_size: int = 0
    skipped_files: list[str] = field(default_factory=list)


def resolve_path(path: str | Path) -> Path:
    """A relative path means the working directory if it exists there, else the repo root."""
    path = Path(path).expanduser()
    if path.is_absolute() or path.exists():
        return path.resolve()
    return (REPO_DIR / path).resolve()


def data_summary(root: str | Path, loaded: LoadedSet) -> dict:
    """A report's `data` entry: the resolved root, the images loaded and those skipped or resized."""
    return {
        "root": str(resolve_path(root)),
        "images": len(loaded.labels),
        "skipped_unreadable": loaded.skipped_unreadable,
        "skipped_files": loaded.skipped_files,
        "resized_wrong_size": loaded.resized_wrong_size,
    }


def scan_dataset(
    root: str | Path,
    class_names: list[str],
    require_all_classes: bool = True,
    extensions: tuple[str, ...] = IMAGE_EXTENSIONS,
) -> list[Sample]:
    """List every image under root; DataError on a layout that cannot be trained on."""
    root = resolve_path(root)
    if not root.is_dir():
        raise DataError(
            f"dataset.root={root} does not exist; run `python run.py task=collect_tactile` "
            "or point dataset.root at a folder <sensor>/<material>/<image>.png"
        )
    sensors = sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(("_", ".")))
    if not sensors:
        raise DataError(
            f"dataset.root={root} has no sensor folders; expected <sensor>/<material>/<image>.png"
        )
    extensions = tuple(e.lower() for e in extensions)
    samples: list[Sample] = []
    for sensor_dir in sensors:
        for material_dir in sorted(
            p for p in sensor_dir.iterdir() if p.is_dir() and not p.name.startswith(("_", "."))
        ):
            if material_dir.name not in class_names:
                raise DataError(
                    f"{material_dir} is a class not in materials={class_names}; add it to materials or move the folder"
                )
            files = sorted(p for p in material_dir.iterdir() if p.suffix.lower() in extensions)
            if not files:
                raise DataError(
                    f"class folder {material_dir} has no images ({'/'.join(extensions)}); fill or remove it"
                )
            label = class_names.index(material_dir.name)
            samples.extend(Sample(f, sensor_dir.name, label) for f in files)
    present = {s.label for s in samples}
    missing = [c for i, c in enumerate(class_names) if i not in present]
    if not present:
        raise DataError(f"dataset.root={root} has no images in <sensor>/<material>/ folders")
    if missing and require_all_classes:
        raise DataError(
            f"dataset.root={root} has no folder for class(es) {missing}; collect them or set materials to the classes present"
        )
    if missing:
        log.warning(
            "dataset %s has no images of %s; those classes are not evaluated", root, missing
        )
    return samples


def load_backgrounds(root: str | Path) -> dict[str, np.ndarray]:
    """`<root>/_backgrounds/<sensor>.png` no-contact frames (RGB), when the data set has them."""
    folder = resolve_path(root) / "_backgrounds"
    out = {}
    for path in sorted(folder.glob("*.png")) if folder.is_dir() else []:
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is not None:
            out[path.stem] = np.ascontiguousarray(bgr[..., ::-1])
    return out


def load_samples(
    samples: list[Sample],
    size: int,
    desc: str = "loading images",
    crop_px: int | None = None,
    backgrounds: dict[str, np.ndarray] | None = None,
) -> LoadedSet:
    """Read, preprocess (optional contact crop, resize) and stack images; skip (and count) unreadable ones."""
    images, labels, sensors, paths, skipped = [], [], [], [], []
    wrong_size = 0
    for sample in tqdm(samples, desc=desc, unit="img", leave=False):
        bgr = cv2.imread(str(sample.path), cv2.IMREAD_COLOR)
        if bgr is None:
            skipped.append(str(sample.path))
            continue
        if bgr.shape[:2] != (DIGIT_HEIGHT, DIGIT_WIDTH):
            wrong_size += 1
        background = (backgrounds or {}).get(sample.sensor)
        images.append(preprocess(bgr[..., ::-1], size, crop_px, background))
        labels.append(sample.label)
        sensors.append(sample.sensor)
        paths.append(str(sample.path))
    if skipped:
        log.warning("skipped %d unreadable image(s), e.g. %s", len(skipped), skipped[0])
    if wrong_size:
        log.warning(
            "%d image(s) were not %dx%d (rows x cols, a DIGIT frame) and were resized",
            wrong_size,
            DIGIT_HEIGHT,
            DIGIT_WIDTH,
        )
    if not images:
        raise DataError(f"none of the {len(samples)} images could be read; check the files")
    return LoadedSet(
        images=np.stack(images),
        labels=np.asarray(labels, dtype=np.int64),
        sensors=np.asarray(sensors),
        paths=paths,
        skipped_unreadable=len(skipped),
        resized_wrong_size=wrong_size,
        skipped_files=skipped,
    )


def stratified_split(
    labels: np.ndarray, sensors: np.ndarray, fractions: tuple[float, float, float], seed: int
) -> dict[str, np.ndarray]:
    """Indices for train/val/test, split separately within each (sensor, class) group.

    Every group of at least 3 images puts at least one image in each split, so each
    finger and class is validated and tested. Same seed, same split.
    """
    if len(labels) != len(sensors):
        raise ValueError(f"labels ({len(labels)}) and sensors ({len(sensors)}) differ in length")
    if len(fractions) != 3 or abs(sum(fractions) - 1.0) > 1e-6 or min(fractions) < 0:
        raise ValueError(
            f"split fractions {fractions} must be three non-negative numbers summing to 1"
        )
    rng = np.random.default_rng(seed)
    parts: dict[str, list[np.ndarray]] = {"train": [], "val": [], "test": []}
    groups = sorted(set(zip(sensors.tolist(), labels.tolist())))
    for sensor, label in groups:
        idx = np.flatnonzero((sensors == sensor) & (labels == label))
        idx = idx[rng.permutation(len(idx))]
        n = len(idx)
        n_val = int(round(n * fractions[1]))
        n_test = int(round(n * fractions[2]))
        if n >= 3:
            n_val, n_test = max(n_val, 1), max(n_test, 1)
        n_val, n_test = min(n_val, n), min(n_test, max(n - n_val, 0))
        parts["val"].append(idx[:n_val])
        parts["test"].append(idx[n_val : n_val + n_test])
        parts["train"].append(idx[n_val + n_test :])
    return {
        k: np.sort(np.concatenate(v)) if v else np.zeros(0, dtype=np.int64)
        for k, v in parts.items()
    }


def class_counts(
    labels: np.ndarray, sensors: np.ndarray, class_names: list[str]
) -> dict[str, dict[str, int]]:
    """{sensor: {class: count}} for manifests and reports."""
    counts = Counter(zip(sensors.tolist(), labels.tolist()))
    return {
        s: {c: int(counts.get((s, i), 0)) for i, c in enumerate(class_names)}
        for s in sorted(set(sensors.tolist()))
    }


def press_kinds(root: str | Path, paths: list[str]) -> np.ndarray | None:
    """Each image's kind of press (centre, edge, feature, ...) from a sim data set's manifest.

    `task=collect_tactile` records it in `manifest.json` (`presses`, keyed by the path
    relative to root); None for data without it (older sim sets, real recordings).
    Images the manifest does not list are "unknown".
    """
    entries = _per_image(root, paths, "presses")
    return None if entries is None else np.asarray([str(e or "unknown") for e in entries])


def curvature_bins(root: str | Path, paths: list[str]) -> np.ndarray | None:
    """Each image's bin of surface curvature at the press (sim/surface_curvature.py), from
    the manifest's `curvatures` (1/m per image); None for data sets without them."""
    entries = _per_image(root, paths, "curvatures")
    if entries is None:
        return None
    return np.asarray([curvature_bin(float("nan") if e is None else float(e)) for e in entries])


def press_groups(root: str | Path, paths: list[str]) -> dict[str, np.ndarray]:
    """Each image's group under every per-image table the manifest has, by report key:
    `per_press_kind` (press_kinds) and `per_curvature` (curvature_bins)."""
    groups = {
        "per_press_kind": press_kinds(root, paths),
        "per_curvature": curvature_bins(root, paths),
    }
    return {key: g for key, g in groups.items() if g is not None}


def _per_image(root: str | Path, paths: list[str], key: str) -> list | None:
    """The manifest's `key` entry of each image (None where it lists none), or None when
    the data set's manifest has no such table."""
    root = resolve_path(root)
    manifest = root / "manifest.json"
    if not manifest.is_file():
        return None
    try:
        table = json.loads(manifest.read_text()).get(key)
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError):
        log.warning("%s is not a readable JSON manifest; no per-%s figures", manifest, key)
        return None
    if not isinstance(table, dict):
        return None
    entries = []
    for path in paths:
        try:
            entries.append(table.get(Path(path).resolve().relative_to(root).as_posix()))
        except ValueError:
            entries.append(None)
    return entries
