"""task=collect_tactile: a labelled tactile material data set from the simulated DIGITs.

    python run.py task=collect_tactile dataset.root=data/tactile/sim

Writes `<root>/<sensor>/<material>/<id>.png`, `<root>/_backgrounds/<sensor>.png` and
`<root>/manifest.json`; how the presses are drawn: sim/tactile_collection.py. This module
only wires the config to it.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

from hydra.utils import to_absolute_path
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.sim.tactile_collection import CollectionSettings, collect_tactile


def run(cfg: DictConfig) -> dict:
    task = OmegaConf.to_container(cfg.task, resolve=True)
    settings = CollectionSettings(**{f.name: task[f.name] for f in fields(CollectionSettings)})
    root = Path(to_absolute_path(str(cfg.task.root)))
    return collect_tactile(root, list(cfg.materials), settings)
