"""The training loop: resume after interruption equals an uninterrupted run; early stopping rule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.classifier import fit as fit_module
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
from neuralfeels_sem.perception.classifier.fit import (
    BEST,
    LAST,
    TrainSettings,
    recalibrate_batchnorm,
)
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.perception.classifier.transforms import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    normalize,
    resize_batch,
    to_tensor,
)
from tests.perception.synthetic_tactile import CLASSES, pressed

SIZE = 32


@pytest.fixture(scope="module")
def arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    labels = np.arange(24) % 4
    images = resize_batch([pressed(i % 4, int(c), rng) for i, c in enumerate(labels)], SIZE)
    return images[:16], labels[:16], images[16:], labels[16:]


def fit(
    arrays,
    run_dir: Path,
    max_epochs: int,
    resume: bool = False,
    patience: int = 10,
    lr: float = 3e-4,
    lr_schedule: str = "constant",
):
    torch.manual_seed(0)
    settings = TrainSettings(
        batch_size=8,
        max_epochs=max_epochs,
        patience=patience,
        lr=lr,
        seed=0,
        lr_schedule=lr_schedule,
    )
    return fit_module.fit(
        build_model(4),
        *arrays,
        settings,
        run_dir,
        CLASSES,
        SIZE,
        list(IMAGENET_MEAN),
        list(IMAGENET_STD),
        torch.device("cpu"),
        resume_from=run_dir / LAST if resume else None,
    )


def test_resumed_run_ends_where_an_uninterrupted_one_does(arrays, tmp_path: Path) -> None:
    straight = fit(arrays, tmp_path / "straight", max_epochs=2)
    first = fit(arrays, tmp_path / "cut", max_epochs=1)
    assert first.epochs_run == 1
    resumed = fit(arrays, tmp_path / "cut", max_epochs=2, resume=True)
    assert resumed.resumed_from_epoch == 1 and resumed.epochs_run == 2
    assert [h["epoch"] for h in resumed.history] == [1, 2]
    assert resumed.history == straight.history
    a = torch.load(tmp_path / "straight" / LAST, weights_only=True)["model"]
    b = torch.load(tmp_path / "cut" / LAST, weights_only=True)["model"]
    for key in a:
        assert torch.equal(a[key], b[key]), key
    best = load_checkpoint(tmp_path / "cut" / BEST)
    assert (
        best.meta["epoch"] == resumed.best_epoch
        and best.meta["val_accuracy"] == resumed.best_val_accuracy
    )


def test_cosine_schedule_runs_from_lr_to_its_floor() -> None:
    settings = TrainSettings(lr=1e-3, lr_schedule="cosine", min_lr_ratio=0.01)
    assert settings.lr_at(0.0) == pytest.approx(1e-3)
    assert settings.lr_at(0.5) == pytest.approx(0.5 * (1e-3 + 1e-5))
    assert settings.lr_at(1.0) == pytest.approx(1e-5)
    lrs = [settings.lr_at(p) for p in np.linspace(0, 1, 11)]
    assert all(a > b for a, b in zip(lrs, lrs[1:]))
    assert TrainSettings(lr=1e-3).lr_at(0.9) == 1e-3  # the paper's constant lr
    with pytest.raises(ValueError, match="lr_schedule"):
        TrainSettings(lr_schedule="step")


def test_resumed_cosine_run_follows_the_same_schedule(
    arrays, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    straight = fit(arrays, tmp_path / "straight", max_epochs=2, lr_schedule="cosine")
    save_last = fit_module._save_last

    def stop_after_first_epoch(path, model, optimizer, generator, state):
        save_last(path, model, optimizer, generator, state)
        if state["epoch"] == 1:
            raise KeyboardInterrupt  # the run is killed once epoch 1 is on disk

    monkeypatch.setattr(fit_module, "_save_last", stop_after_first_epoch)
    with pytest.raises(KeyboardInterrupt):
        fit(arrays, tmp_path / "cut", max_epochs=2, lr_schedule="cosine")
    monkeypatch.setattr(fit_module, "_save_last", save_last)
    resumed = fit(arrays, tmp_path / "cut", max_epochs=2, resume=True, lr_schedule="cosine")
    assert resumed.resumed_from_epoch == 1
    assert resumed.history == straight.history
    ends = [h["lr_end"] for h in straight.history]
    assert ends[0] < 3e-4 and ends[1] < ends[0]


def test_early_stopping_rule(arrays, tmp_path: Path) -> None:
    result = fit(arrays, tmp_path, max_epochs=6, patience=1, lr=1e-9)
    vals = [h["val_accuracy"] for h in result.history]
    assert result.best_val_accuracy == max(vals) and vals[result.best_epoch - 1] == max(vals)
    # stops exactly `patience` epochs after the best one, unless max_epochs came first
    assert result.epochs_run == min(result.best_epoch + 1, 6)
    assert result.stopped_early == (
        result.epochs_run < 6 or result.epochs_run - result.best_epoch >= 1
    )


def test_too_little_data_is_a_data_error(arrays, tmp_path: Path) -> None:
    x, y, vx, vy = arrays
    with pytest.raises(DataError, match="too few images"):
        fit((x[:1], y[:1], vx, vy), tmp_path, max_epochs=1)


def test_batchnorm_recalibration_uses_current_weights() -> None:
    torch.manual_seed(0)
    conv = torch.nn.Conv2d(3, 4, 1)
    model = torch.nn.Sequential(conv, torch.nn.BatchNorm2d(4, momentum=0.1))
    model[1].running_mean.fill_(7.0)  # stale statistics from "older weights"
    images = np.random.default_rng(0).integers(0, 256, (8, 6, 6, 3), dtype=np.uint8)
    recalibrate_batchnorm(
        model, images, [0.5, 0.5, 0.5], [0.25, 0.25, 0.25], torch.device("cpu"), batch_size=8
    )
    with torch.no_grad():
        features = conv(normalize(to_tensor(images), [0.5, 0.5, 0.5], [0.25, 0.25, 0.25]))
    torch.testing.assert_close(model[1].running_mean, features.mean(dim=(0, 2, 3)))
    torch.testing.assert_close(model[1].running_var, features.var(dim=(0, 2, 3), unbiased=True))
    assert model[1].momentum == 0.1 and not model.training


def test_gated_report_counts_what_the_mapper_would_label() -> None:
    from neuralfeels_sem.perception.classifier.evaluate import gated_report

    y = np.array([0, 1, 2, 3, 0])
    probs = np.array(
        [
            [0.9, 0.1, 0.0, 0.0],  # confident, right, inside
            [0.5, 0.4, 0.1, 0.0],  # not confident
            [0.0, 0.05, 0.95, 0.0],  # confident, right, at the edge
            [0.85, 0.0, 0.0, 0.15],  # confident, wrong, inside
            [0.7, 0.3, 0.0, 0.0],  # confident at 0.6 only
        ]
    )
    edges = np.array([0.1, 0.1, 0.8, 0.2, 0.0])
    gated = gated_report(y, probs, edges, 0.8, 0.5)
    assert gated["kept_count"] == 2 and gated["kept_share"] == pytest.approx(0.4)
    assert gated["accuracy_kept"] == pytest.approx(0.5)
    assert gated["left_out_low_confidence"] == 2 and gated["left_out_edge"] == 1
    no_edge_check = gated_report(y, probs, edges, 0.6, 1.0)
    assert no_edge_check["kept_count"] == 4 and no_edge_check["accuracy_kept"] == pytest.approx(
        0.75
    )
    with pytest.raises(ValueError, match="lengths differ"):
        gated_report(y[:2], probs, edges, 0.8, 0.5)
