"""task=collect_tactile: a labelled tactile material data set, simulated or from real DIGITs.

    python run.py task=collect_tactile dataset.root=data/tactile/sim
    python run.py task=collect_tactile sensor=real task.material=metal dataset.root=data/tactile/real

Writes `<root>/<sensor>/<material>/<id>.png`, `<root>/_backgrounds/<sensor>.png` and
`<root>/manifest.json`. sensor=sim renders presses (sim/tactile_collection.py);
sensor=real records contact frames while an object of `task.material` is pressed on the
DIGITs (sensors/real/tactile_recording.py), appending to an earlier recording. This
module only wires the config to them.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

from hydra.utils import instantiate, to_absolute_path
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.configs.dataset import TactileDatasetConfig
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.contact import ContactGate
from neuralfeels_sem.sensors.real.tactile_recording import RecordingSettings, record_tactile


def run(cfg: DictConfig) -> dict:
    root = Path(to_absolute_path(str(cfg.task.root)))
    if cfg.sensor.name == "real":
        return _record_real(cfg, root)
    if cfg.sensor.name != "sim":
        raise ConfigError(
            f"task=collect_tactile collects from sensor=sim or sensor=real, not sensor={cfg.sensor.name}"
        )
    # Imported here so that a rig without MuJoCo or pyrender records real data.
    from neuralfeels_sem.sim.tactile_collection import CollectionSettings, collect_tactile

    task = OmegaConf.to_container(cfg.task, resolve=True)
    settings = CollectionSettings(**{f.name: task[f.name] for f in fields(CollectionSettings)})
    return collect_tactile(root, list(cfg.materials), settings)


def _record_real(cfg: DictConfig, root: Path) -> dict:
    if root == Path(to_absolute_path(TactileDatasetConfig().root)):
        raise ConfigError(
            f"sensor=real would record into {TactileDatasetConfig().root}, the simulated data "
            "set's default folder: give real data its own, e.g. dataset.root=data/tactile/real"
        )
    if cfg.sensor.digit is None:
        raise ConfigError("sensor.digit is null: task=collect_tactile sensor=real needs the DIGITs")
    if "contact_threshold" not in cfg.classifier:
        raise ConfigError(
            "task=collect_tactile gates contact as classifier=efficientnet_b0 does: drop classifier=oracle"
        )
    # The gate the classifier applies at run time, so the data holds what it will be shown.
    gate = ContactGate(
        cfg.classifier.contact_threshold,
        cfg.classifier.contact_min_area,
        cfg.classifier.contact_blur_px,
    )
    task = cfg.task
    settings = RecordingSettings(
        material=task.material,
        max_images=task.max_images,
        duration_s=task.duration_s,
        min_change=task.min_change,
    )
    digits = instantiate(cfg.sensor.digit)
    return record_tactile(root, list(cfg.materials), digits.cameras, gate, settings)
