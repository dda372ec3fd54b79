"""Checks of a composed config that need files or the machine, before any heavy set-up.

Run by tasks/run_guard.py within seconds of start, after the schema checks
(configs.validate_config: ranges, durations, seeds, unknown keys) and before the simulator,
classifier or field is built:
- every file the command line names: the recording (sensor=replay), the classifier
  checkpoint, a custom object's mesh (its NaN vertices and face count against MuJoCo's
  limit too) and label file, the tactile depth checkpoint;
- settings the task would silently ignore (`classifier.weights` outside training);
- the field's hash table against the memory available to hold it;
- the live view's optional extra (`viz.live=rerun` needs rerun-sdk).
Each refusal raises a UserError with one line naming the key and the fix.
"""

from __future__ import annotations

import math
from pathlib import Path

from omegaconf import DictConfig

from neuralfeels_sem.core.errors import ConfigError, DataError

# Tasks that read classifier.weights (the ImageNet backbone training starts from).
TASKS_READING_WEIGHTS = ("train_classifier", "classifier_experiment")
# Tasks that build the semantic field (its hash table).
TASKS_BUILDING_A_FIELD = ("map",)
FLOAT_BYTES = 4  # the table is float32


def preflight(cfg: DictConfig) -> None:
    """Every check of this module, cheapest first; raises a UserError on the first failure."""
    check_ignored_settings(cfg)
    check_live_view(cfg)
    check_table_memory(cfg)
    check_recording(cfg)
    check_checkpoints(cfg)
    check_custom_mesh(cfg)


def check_ignored_settings(cfg: DictConfig) -> None:
    """Refuse `classifier.weights` on a task that would ignore it."""
    weights = cfg.get("classifier", {}).get("weights")
    task = str(cfg.task.get("name"))
    if weights is not None and task not in TASKS_READING_WEIGHTS:
        raise ConfigError(
            f"classifier.weights={weights} is read only by task=train_classifier (the backbone "
            f"training starts from) and task={task} would ignore it; to use a trained classifier "
            "set classifier.checkpoint=PATH instead"
        )


def check_live_view(cfg: DictConfig) -> None:
    """Refuse `viz.live=rerun` on a map run where rerun-sdk does not import."""
    live = str(cfg.get("viz", {}).get("live", "none"))
    if live != "rerun" or str(cfg.task.get("name")) not in TASKS_BUILDING_A_FIELD:
        return
    from neuralfeels_sem.viz.live import INSTALL_HINT, rerun_import_error

    error = rerun_import_error()
    if error is not None:
        raise ConfigError(
            f"viz.live=rerun needs the optional rerun-sdk package ({error}): "
            f"install it with {INSTALL_HINT}, or set viz.live=none"
        )


def hash_table_bytes(encoding: DictConfig, log2_table_size: int | None = None) -> int:
    """Memory the field's hash table takes while training (fields/hash_grid.py's rows),
    with `model.encoding`'s table size or `log2_table_size`."""
    size = encoding.log2_table_size if log2_table_size is None else log2_table_size
    table = 2 ** int(size)
    rows = 0
    for level in range(int(encoding.num_levels)):
        resolution = math.floor(encoding.base_resolution * encoding.per_level_scale**level)
        rows += min((resolution + 1) ** 3, table)
    # The table and Adam's two moments, plus a dense gradient unless the gradient is
    # row-sparse (model.encoding.sparse_grad; fields/optim.py FieldAdam).
    copies = 3 if encoding.get("sparse_grad", True) else 4
    return rows * int(encoding.features_per_level) * FLOAT_BYTES * copies


def available_memory_bytes() -> int | None:
    """MemAvailable from /proc/meminfo (Linux); None where it cannot be read."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def field_memory(device: str) -> tuple[int | None, str]:
    """Free bytes where the field will live, and its name: the GPU's for a CUDA device
    (`device`, as configured), else the machine's memory."""
    if device == "cpu":
        return available_memory_bytes(), "memory"
    import torch

    if not torch.cuda.is_available():
        return available_memory_bytes(), "memory"
    index = torch.device("cuda" if device == "auto" else device).index
    free, _ = torch.cuda.mem_get_info(index if index is not None else 0)
    return int(free), "GPU memory"


def check_table_memory(cfg: DictConfig, available: int | None = None) -> None:
    """Refuse a hash table (with its training state) larger than the free memory of the
    device the field lives on (`available` bytes when given)."""
    if str(cfg.task.get("name")) not in TASKS_BUILDING_A_FIELD or "encoding" not in cfg.model:
        return
    where = "memory"
    if available is None:
        available, where = field_memory(str(cfg.get("device", "auto")))
    need = hash_table_bytes(cfg.model.encoding)
    if available is None or need <= available:
        return
    size = int(cfg.model.encoding.log2_table_size)
    fits = size
    while fits > 4 and hash_table_bytes(cfg.model.encoding, fits) > available:
        fits -= 1
    raise ConfigError(
        f"model.encoding.log2_table_size={size} needs {need / 1e9:.1f} GB for the hash table "
        f"and its training state, but {available / 1e9:.1f} GB of {where} is available; "
        f"use model.encoding.log2_table_size={fits} or less"
    )


def check_recording(cfg: DictConfig) -> None:
    """sensor=replay: the recording opens (meta.json, frames, classes) before set-up."""
    if not str(cfg.sensor.get("_target_", "")).endswith("ReplaySensor"):
        return
    from neuralfeels_sem.sensors.replay.replay_sensor import ReplaySensor

    if cfg.sensor.format == "feelsight":
        recording = Path(str(cfg.sensor.recording or "")).expanduser()
        depth = recording / "realsense" / str(cfg.sensor.camera) / "depth.npz"
        if cfg.sensor.recording and (recording / "data.pkl").is_file():
            # its depth stack is large: read once, by the run itself
            if not depth.is_file():
                raise DataError(
                    f"FeelSight log depth {depth} is missing: restore it, or pick the camera "
                    "it has with sensor.camera"
                )
            return
    ReplaySensor(
        recording=cfg.sensor.recording,
        format=cfg.sensor.format,
        camera=cfg.sensor.camera,
        class_names=list(cfg.materials),
    ).read_recording()  # no warnings here: the run reports the recording's damage once


def check_checkpoints(cfg: DictConfig) -> None:
    """A classifier or tactile depth checkpoint given on the command line exists and loads."""
    classifier = cfg.get("classifier", {}).get("checkpoint")
    if classifier:
        from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
        from neuralfeels_sem.perception.classifier.dataset import resolve_path

        path = resolve_path(classifier)
        _existing_file("classifier.checkpoint", path)
        trained_for = load_checkpoint(path).class_names
        if trained_for != list(cfg.materials):
            raise ConfigError(
                f"classifier.checkpoint={path} was trained for {trained_for} but "
                f"materials={list(cfg.materials)}; set materials to match or train a classifier "
                "for these classes"
            )
    depth = cfg.mapping.get("mapper", {}).get("tactile_depth", {}) if "mapping" in cfg else {}
    if depth.get("checkpoint") and depth.get("source") == "net":
        from neuralfeels_sem.perception.tactile_depth_net.checkpoint import (
            load_checkpoint as load_depth_checkpoint,
        )

        path = Path(str(depth.checkpoint)).expanduser()
        _existing_file("mapping.mapper.tactile_depth.checkpoint", path)
        load_depth_checkpoint(path)


def _existing_file(key: str, path: Path) -> None:
    if path.is_dir():
        raise DataError(f"{key}={path} is a directory: give the path of a file inside it")
    if not path.is_file():
        raise DataError(f"{key}={path} does not exist: give the path of an existing file")


def check_custom_mesh(cfg: DictConfig) -> None:
    """object=custom: the mesh and label files exist; the mesh has no NaN vertices and
    no more faces than MuJoCo takes (objects/custom.py read_mesh)."""
    if not str(cfg.object.get("_target_", "")).endswith("load_custom_object"):
        return
    from neuralfeels_sem.objects.custom import read_mesh, resolve_path

    read_mesh(resolve_path(cfg.object.mesh, "object.mesh"))
    if cfg.object.get("labels"):
        resolve_path(cfg.object.labels, "object.labels")
