"""task=train_tactile_depth: train the tactile depth network on simulator renders.

    python run.py task=train_tactile_depth [task.train_samples=2000 task.epochs=10]

Renders its own presses (sim/tactile_depth_collection.py), trains
(perception/tactile_depth_net/train.py) and writes into the run directory
tactile_depth.pt, report.json (contact IoU and depth MAE on the held-out set, overall and
per finger) and history.json. This module only wires the config to them.
"""

from __future__ import annotations

import sys
from pathlib import Path

from hydra.utils import to_absolute_path
from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.perception.tactile_depth_net.compose import Augmentation
from neuralfeels_sem.perception.tactile_depth_net.fit import FitSettings
from neuralfeels_sem.perception.tactile_depth_net.train import DepthSet, train_tactile_depth
from neuralfeels_sem.sim.tactile_depth_collection import (
    DepthPressSettings,
    depth_backgrounds,
    render_depth_samples,
)
from neuralfeels_sem.tasks.runner import output_dir
from neuralfeels_sem.utils.paths import SHARED_DATA_DIR

HELD_OUT_BACKGROUND_SEED = 10000


def run(cfg: DictConfig) -> dict:
    task = cfg.task
    if int(task.held_out_seed) == int(task.seed):
        raise ConfigError(
            f"task.held_out_seed={task.held_out_seed} equals task.seed: pick another held-out seed"
        )
    real = _real_backgrounds(task.real_backgrounds)
    presses = _press_settings(task)
    classes = list(cfg.materials)
    train = _depth_set(
        render_depth_samples(int(task.train_samples), classes, presses, int(task.seed)),
        depth_backgrounds(
            list(range(int(task.procedural_backgrounds))), real, (1, task.real_held_out_every)
        ),
    )
    held_seeds = range(
        HELD_OUT_BACKGROUND_SEED, HELD_OUT_BACKGROUND_SEED + task.held_out_procedural_backgrounds
    )
    held_out = _depth_set(
        render_depth_samples(int(task.held_out_samples), classes, presses, int(task.held_out_seed)),
        depth_backgrounds(list(held_seeds), real, (0, task.real_held_out_every)),
    )
    settings = FitSettings(
        width=int(task.width),
        input_size=(int(task.input_size[0]), int(task.input_size[1])),
        epochs=int(task.epochs),
        batch_size=int(task.batch_size),
        lr=float(task.lr),
        depth_weight=float(task.depth_weight),
        augmentation=Augmentation(
            float(task.max_noise_std), float(task.max_gain_drift), float(task.max_offset_drift)
        ),
        seed=int(task.seed),
    )
    provenance = {"command": " ".join(["python", "run.py", *sys.argv[1:]]), "materials": classes}
    return train_tactile_depth(
        train,
        held_out,
        settings,
        output_dir(),
        min_contact_px=int(cfg.mapping.mapper.tactile_depth.min_contact_px),
        export_fp16=bool(task.export_fp16),
        provenance=provenance,
    )


def _press_settings(task: DictConfig) -> DepthPressSettings:
    return DepthPressSettings(
        sensors=list(task.sensors),
        library_objects=list(task.library_objects),
        firmness_mm={k: float(v) for k, v in task.firmness_mm.items()},
        firmness_spread=float(task.firmness_spread),
        uniform_press_fraction=float(task.uniform_press_fraction),
        min_press_mm=float(task.min_press_mm),
        miss_fraction=float(task.miss_fraction),
        max_gap_mm=float(task.max_gap_mm),
        max_tilt_deg=float(task.max_tilt_deg),
        edge_press_fraction=float(task.edge_press_fraction),
        edge_tilt_deg=[float(v) for v in task.edge_tilt_deg],
        texture_scale=float(task.texture_scale),
    )


def _real_backgrounds(spec: str | None) -> Path | None:
    """auto -> the shared real frames when present; null -> none; a folder -> it (checked)."""
    if spec is None:
        return None
    if spec == "auto":
        folder = SHARED_DATA_DIR / "digit_real" / "backgrounds"
        return folder if folder.is_dir() else None
    folder = Path(to_absolute_path(spec))
    if not folder.is_dir():
        raise DataError(
            f"task.real_backgrounds={spec} is not a folder: pass a folder of empty DIGIT frames or null"
        )
    return folder


def _depth_set(samples, backgrounds) -> DepthSet:
    frames, names = backgrounds
    return DepthSet(samples.change, samples.press_mm, samples.finger, frames, names)
