"""task=train_tactile_depth end to end through run.py at a tiny size, and its config checks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from neuralfeels_sem.configs.tactile_depth import TrainTactileDepthTaskConfig
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import load_checkpoint
from neuralfeels_sem.tasks.train_tactile_depth import run
from tests.helpers import compose_config, run_cli

TINY = [
    "task.train_samples=8",
    "task.held_out_samples=4",
    "task.epochs=1",
    "task.batch_size=4",
    "task.procedural_backgrounds=2",
    "task.held_out_procedural_backgrounds=1",
    "task.library_objects=[]",
    "task.width=4",
    "task.input_size=[64,48]",
]


@pytest.mark.slow
def test_training_writes_checkpoint_and_held_out_report(tmp_path: Path) -> None:
    result = run_cli(["task=train_tactile_depth", f"hydra.run.dir={tmp_path}", *TINY])
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["train_samples"] == 8 and report["held_out_samples"] == 4
    held_out = report["held_out"]
    assert set(held_out["per_finger"]) == {"index", "middle", "ring", "thumb"}
    assert 0.0 <= held_out["overall"]["contact_iou"] <= 1.0
    assert held_out["overall"]["depth_mae_mm"] >= 0.0
    ckpt = load_checkpoint(tmp_path / "tactile_depth.pt")
    assert ckpt.width == 4 and ckpt.input_size == (64, 48)
    assert len(json.loads((tmp_path / "history.json").read_text())) == 1


def test_the_task_config_composes_with_its_schema_defaults() -> None:
    cfg = compose_config(["task=train_tactile_depth"])
    assert cfg.task.epochs == TrainTactileDepthTaskConfig().epochs
    assert cfg.task.seed == cfg.seed


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ({"batch_size": 1}, "task.batch_size=1"),
        ({"input_size": [16, 16]}, "task.input_size"),
        ({"miss_fraction": 1.5}, "task.miss_fraction=1.5"),
        ({"firmness_mm": {"pinky": 1.0}}, "unknown finger 'pinky'"),
    ],
)
def test_bad_settings_name_the_key(override: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        TrainTactileDepthTaskConfig(**override)


def test_the_same_seed_for_held_out_is_refused() -> None:
    cfg = compose_config(["task=train_tactile_depth", "task.held_out_seed=0", *TINY])
    with pytest.raises(ConfigError, match="task.held_out_seed=0 equals task.seed"):
        run(cfg)
