"""task=train_classifier and task=eval_classifier end to end through run.py, on tiny synthetic data."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
from neuralfeels_sem.perception.classifier.train import resume_path
from tests.helpers import run_cli
from tests.perception.synthetic_tactile import CLASSES, SENSORS, make_dataset

# Tiny input and batch keep each run to seconds on a CPU; the recipe's defaults are 224 / 32.
FAST = ["classifier.input_size=32", "task.batch_size=16", "device=cpu"]


def train(root: Path, run_dir: Path, *extra: str):
    return run_cli(
        ["task=train_classifier", f"dataset.root={root}", f"hydra.run.dir={run_dir}", *FAST, *extra]
    )


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    return make_dataset(tmp_path_factory.mktemp("tactile"), per_group=3)


@pytest.fixture(scope="module")
def trained(data: Path, tmp_path_factory) -> Path:
    # crop_px: inference preprocesses as training did only if every checkpoint says so.
    run_dir = tmp_path_factory.mktemp("run")
    result = train(data, run_dir, "task.max_epochs=2", "classifier.crop_px=64")
    assert result.returncode == 0, result.stderr[-3000:]
    return run_dir


def test_training_writes_all_outputs(trained: Path) -> None:
    for name in (
        "classifier.pt",
        "report.json",
        "confusion.png",
        "per_sensor.png",
        "best.pt",
        "last.pt",
        "split.json",
        "history.json",
    ):
        assert (trained / name).is_file(), name
    report = json.loads((trained / "report.json").read_text())
    for key in ("test_accuracy", "val_accuracy", "per_sensor", "confusion"):
        assert key in report
    assert set(report["per_sensor"]) == set(SENSORS)
    assert report["counts"] == {
        "train": 16,
        "val": 16,
        "test": 16,
    }  # 3 per (sensor, class): 1 / 1 / 1
    confusion = report["confusion"]
    assert len(confusion) == 4 and sum(map(sum, confusion)) == 16
    correct = sum(confusion[i][i] for i in range(4))
    assert report["test_accuracy"] == pytest.approx(correct / 16)
    assert report["training"]["epochs_run"] == 2 and report["training"]["input_size"] == 32
    ckpt = load_checkpoint(trained / "classifier.pt")
    assert ckpt.class_names == CLASSES and ckpt.input_size == 32
    assert ckpt.meta["test_accuracy"] == report["test_accuracy"]
    split = json.loads((trained / "split.json").read_text())
    assert not set(split["train"]) & set(split["test"]) and not set(split["val"]) & set(
        split["test"]
    )


def test_every_checkpoint_records_the_contact_crop(trained: Path) -> None:
    # best.pt must be usable as classifier.checkpoint on its own (e.g. while training runs).
    for name in ("classifier.pt", "best.pt"):
        assert load_checkpoint(trained / name).meta["crop_px"] == 64, name


def test_rerun_in_the_same_run_dir_resumes_from_last_checkpoint(tmp_path: Path) -> None:
    assert resume_path("auto", tmp_path) is None
    (tmp_path / "last.pt").write_bytes(b"")
    assert resume_path("auto", tmp_path) == tmp_path / "last.pt"
    assert resume_path("never", tmp_path) is None
    assert resume_path(str(tmp_path), tmp_path / "elsewhere") == tmp_path / "last.pt"
    with pytest.raises(ConfigError, match="task.resume"):
        resume_path(str(tmp_path / "missing"), tmp_path)


def test_eval_classifier_writes_the_same_report(data: Path, trained: Path, tmp_path: Path) -> None:
    result = run_cli(
        [
            "task=eval_classifier",
            f"dataset.root={data}",
            f"classifier.checkpoint={trained / 'classifier.pt'}",
            f"hydra.run.dir={tmp_path}",
            "device=cpu",
        ]
    )
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["test_count"] == 48 and set(report["per_sensor"]) == set(SENSORS)
    assert sum(map(sum, report["confusion"])) == 48
    gated = report["gated"]  # the synthetic set has _backgrounds/: the mapper's view is scored
    assert gated["max_edge_share"] == 0.5 and 0 <= gated["kept_count"] <= 48
    left_out = gated["left_out_low_confidence"] + gated["left_out_edge"]
    assert gated["kept_count"] + left_out == 48
    assert (
        report["val_accuracy"] == json.loads((trained / "report.json").read_text())["val_accuracy"]
    )
    assert (tmp_path / "confusion.png").is_file() and (tmp_path / "per_sensor.png").is_file()


def test_checkpoint_with_other_classes_fails_with_one_line(
    data: Path, trained: Path, tmp_path: Path
) -> None:
    result = run_cli(
        [
            "task=eval_classifier",
            f"dataset.root={data}",
            f"classifier.checkpoint={trained / 'classifier.pt'}",
            f"hydra.run.dir={tmp_path}",
            "materials=[plastic,metal,fabric]",
        ]
    )
    assert result.returncode == 2
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "trained for" in errors[0] and "Traceback" not in result.stderr


def test_dataset_missing_a_class_fails_with_one_line(tmp_path: Path) -> None:
    root = make_dataset(tmp_path / "d", per_group=1, classes=CLASSES[:3], sensors=("index",))
    result = train(root, tmp_path / "run", "task.max_epochs=1")
    assert result.returncode == 2
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "wood" in errors[0]
