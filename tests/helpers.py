"""Small helpers shared by tests: compose configs and run the CLI."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from neuralfeels_sem.configs import register_configs
from neuralfeels_sem.utils.paths import REPO_DIR

CONF_DIR = REPO_DIR / "conf"


def compose_config(
    overrides: list[str] | None = None, return_hydra_config: bool = False
) -> DictConfig:
    register_configs()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose("config", overrides=overrides or [], return_hydra_config=return_hydra_config)


def run_cli(
    args: list[str], cwd: Path | None = None, timeout: float = 600
) -> subprocess.CompletedProcess:
    """Run `python run.py ARGS` in a subprocess, as a user would."""
    env = dict(os.environ, HYDRA_FULL_ERROR="0", PYTHONUNBUFFERED="1")
    return subprocess.run(
        [sys.executable, str(REPO_DIR / "run.py"), *args],
        cwd=cwd or REPO_DIR,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


# Mapping at toy size (seconds, not minutes): few steps, coarse scoring, no pictures.
TOY_MAPPING = [
    "mapping.mapper.warmup_steps=20",
    "mapping.mapper.steps_per_frame=3",
    "mapping.checkpoint_every=0",
    "eval.every_k_frames=3",
    "eval.num_surface_samples=2000",
    "eval.image_views=2",
    "eval.image_size=64",
    "eval.mesh_resolution=48",
    "eval.shape_samples=2000",
    "viz.plots=false",
]
