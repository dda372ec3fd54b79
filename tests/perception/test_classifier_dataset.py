"""Data set scanning, loading and the stratified split: errors are explicit, nothing dropped silently."""

from __future__ import annotations

import logging
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.classifier.dataset import (
    class_counts,
    load_samples,
    scan_dataset,
    stratified_split,
)
from tests.perception.synthetic_tactile import CLASSES, SENSORS, make_dataset


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    return make_dataset(tmp_path_factory.mktemp("tactile"), per_group=3)


def test_scan_lists_every_image_and_ignores_underscore_folders(tiny: Path) -> None:
    samples = scan_dataset(tiny, CLASSES)
    assert len(samples) == len(SENSORS) * len(CLASSES) * 3
    assert {s.sensor for s in samples} == set(SENSORS)  # not "_backgrounds"
    assert Counter(s.label for s in samples) == {i: 12 for i in range(4)}
    first = samples[0]
    assert (
        first.path.parent.name == CLASSES[first.label]
        and first.path.parent.parent.name == first.sensor
    )


def test_load_resizes_and_counts(tmp_path: Path) -> None:
    root = make_dataset(tmp_path / "d", per_group=1, sensors=("index",))
    odd = np.full((100, 80, 3), 7, np.uint8)
    cv2.imwrite(str(root / "index" / "wood" / "odd.png"), odd)
    (root / "index" / "metal" / "broken.png").write_bytes(b"not an image")
    loaded = load_samples(scan_dataset(root, CLASSES), size=48)
    assert loaded.images.shape == (5, 48, 48, 3)
    assert loaded.skipped_unreadable == 1 and loaded.resized_wrong_size == 1
    assert loaded.skipped_files[0].endswith("broken.png")
    assert sorted(loaded.labels.tolist()) == [0, 1, 2, 3, 3]
    i = [j for j, p in enumerate(loaded.paths) if p.endswith("odd.png")][0]
    assert (loaded.images[i] == 7).all()


def test_missing_root_unknown_empty_and_missing_class(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="does not exist"):
        scan_dataset(tmp_path / "nowhere", CLASSES)
    (tmp_path / "empty_root").mkdir()
    with pytest.raises(DataError, match="no sensor folders"):
        scan_dataset(tmp_path / "empty_root", CLASSES)
    root = make_dataset(tmp_path / "three", per_group=1, classes=CLASSES[:3], sensors=("index",))
    with pytest.raises(DataError, match=r"no folder for class\(es\) \['wood'\]"):
        scan_dataset(root, CLASSES)
    assert (
        len(scan_dataset(root, CLASSES, require_all_classes=False)) == 3
    )  # evaluation may lack a class
    (root / "index" / "wood").mkdir()
    with pytest.raises(DataError, match="has no images"):
        scan_dataset(root, CLASSES)
    (root / "index" / "wood").rmdir()
    (root / "index" / "glass").mkdir()
    with pytest.raises(DataError, match="not in materials"):
        scan_dataset(root, CLASSES)


def test_all_unreadable_is_an_error(tmp_path: Path, caplog) -> None:
    folder = tmp_path / "index" / "plastic"
    folder.mkdir(parents=True)
    (folder / "a.png").write_bytes(b"x")
    with pytest.raises(DataError, match="none of the 1 images"), caplog.at_level(logging.WARNING):
        load_samples(scan_dataset(tmp_path, CLASSES, require_all_classes=False), 32)
    assert "skipped 1 unreadable" in caplog.text


def test_stratified_split_proportions_no_leakage_and_seeded() -> None:
    sensors = np.repeat(np.array(SENSORS), 4 * 40)
    labels = np.tile(np.repeat(np.arange(4), 40), 4)
    parts = stratified_split(labels, sensors, (0.7, 0.15, 0.15), seed=0)
    allidx = np.concatenate(list(parts.values()))
    assert len(allidx) == len(labels) and len(np.unique(allidx)) == len(
        labels
    )  # a partition: no leakage
    for name, expected in (("train", 28), ("val", 6), ("test", 6)):
        counts = class_counts(labels[parts[name]], sensors[parts[name]], ["a", "b", "c", "d"])
        assert all(n == expected for per in counts.values() for n in per.values()), (name, counts)
    again = stratified_split(labels, sensors, (0.7, 0.15, 0.15), seed=0)
    other = stratified_split(labels, sensors, (0.7, 0.15, 0.15), seed=1)
    assert all(np.array_equal(parts[k], again[k]) for k in parts)
    assert not np.array_equal(parts["test"], other["test"])


def test_small_groups_still_reach_every_split() -> None:
    labels = np.array([0, 0, 0, 1, 1, 1, 1])
    sensors = np.array(["index"] * 7)
    parts = stratified_split(labels, sensors, (0.7, 0.15, 0.15), seed=0)
    for name in ("val", "test"):
        assert sorted(labels[parts[name]].tolist()) == [0, 1]
    with pytest.raises(ValueError):
        stratified_split(labels, sensors, (0.5, 0.5, 0.5), seed=0)
