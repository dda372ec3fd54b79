"""Fine-tuning the classifier from a checkpoint on real-like data mixed with a sim set by ratio."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.perception.classifier.finetune import MixedDraw
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.tasks.runner import redirect_output
from neuralfeels_sem.tasks.train_classifier import run
from tests.helpers import compose_config
from tests.perception.synthetic_tactile import CLASSES, make_dataset

SIZE = 32  # tiny input: one epoch takes seconds on a CPU


def draws(draw: MixedDraw, epochs: int = 1) -> list[np.ndarray]:
    generator = torch.Generator().manual_seed(0)
    return [draw(generator) for _ in range(epochs)]


def test_every_epoch_draws_the_real_share() -> None:
    draw = MixedDraw(primary=30, extra=100, real_ratio=0.25)
    for order in draws(draw, 3):
        real, sim = order[order < 30], order[order >= 30]
        assert sorted(real) == list(range(30))  # every real image once
        assert len(sim) == 90 and len(set(sim)) == 90 and sim.max() < 130  # no repeats
        assert len(real) / len(order) == 0.25
    # Each batch of 16 holds about the ratio of real images too (shuffled together).
    shares = [(b < 30).mean() for b in np.array_split(draws(draw)[0], 120 // 16)]
    assert 0.1 < np.mean(shares) < 0.4
    assert sorted(draws(MixedDraw(30, 100, 1.0))[0]) == list(range(30))


def test_a_small_sim_set_is_drawn_with_replacement() -> None:
    order = draws(MixedDraw(primary=30, extra=10, real_ratio=0.25))[0]
    sim = order[order >= 30]
    assert len(sim) == 90 and set(sim) <= set(range(30, 40))
    assert (order < 30).sum() == 30


def checkpoint(path: Path, classes: list[str]) -> Path:
    torch.manual_seed(0)
    return save_checkpoint(path, build_model(len(classes)), classes, SIZE, [0.5] * 3, [0.25] * 3)


def cfg(real: Path, sim: Path, init: Path, *extra: str):
    return compose_config(
        [
            "task=train_classifier",
            f"dataset.root={real}",
            f"dataset.sim_root={sim}",
            f"task.init_from={init}",
            "task.real_ratio=0.25",
            "task.max_epochs=1",
            "task.batch_size=16",
            "task.resume=never",
            "device=cpu",
            *extra,
        ]
    )


@pytest.fixture(scope="module")
def sets(tmp_path_factory) -> tuple[Path, Path]:
    # The real set lacks wood: the sim set supplies it for training.
    real = make_dataset(tmp_path_factory.mktemp("real"), 4, ("index",), CLASSES[:3], seed=1)
    sim = make_dataset(tmp_path_factory.mktemp("sim"), 4, ("index", "thumb"), seed=2)
    return real, sim


def test_fine_tunes_a_checkpoint_on_the_mix(sets, tmp_path: Path) -> None:
    real, sim = sets
    init = checkpoint(tmp_path / "init.pt", CLASSES)
    run_dir = tmp_path / "run"
    # A learning rate of ~0 leaves the weights where they started: the checkpoint's.
    with redirect_output(run_dir):
        report = run(cfg(real, sim, init, "task.lr=1e-12", "classifier.input_size=64"))
    mix = report["training"]["mix"]
    assert mix["sim_images"] == 32 and mix["real_train_images"] == 6  # 3 classes x 2 of 4
    assert mix["sim_per_epoch"] == 18 and report["training"]["input_size"] == SIZE
    history = json.loads((run_dir / "history.json").read_text())
    assert history[0]["real_drawn"] == 6 and history[0]["extra_drawn"] == 18
    tuned = load_checkpoint(run_dir / "classifier.pt")
    assert tuned.class_names == CLASSES and tuned.input_size == SIZE
    start = load_checkpoint(init).state_dict
    name = next(k for k in start if k.endswith("weight") and start[k].ndim == 4)
    assert torch.allclose(tuned.state_dict[name], start[name], atol=1e-6)
    assert report["counts"]["test"] == 3  # validation and test only on the real set


def test_checkpoint_of_other_classes_is_refused(sets, tmp_path: Path) -> None:
    real, sim = sets
    init = checkpoint(tmp_path / "init.pt", CLASSES[:3])
    with redirect_output(tmp_path / "run"), pytest.raises(ConfigError) as error:
        run(cfg(real, sim, init))
    message = str(error.value)
    assert str(CLASSES[:3]) in message and str(CLASSES) in message and "\n" not in message
