"""Schema for the top-level keys of conf/config.yaml and for conf/task/."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from neuralfeels_sem.core.limits import check_seed
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS


@dataclass
class RootConfig:
    seed: int = 0
    # The classifier's classes, in its output order (default: neuralfeels_sem/core/materials.py).
    materials: list[str] = field(default_factory=lambda: list(DEFAULT_MATERIALS))
    device: str = "auto"  # auto | cpu | cuda | cuda:N
    # torch CPU threads: auto (OMP_NUM_THREADS, else 1: measured, utils/device.py) | N
    threads: str = "auto"
    run_dir: Any = None  # an existing run directory, for task=eval
    # Config groups (their own schemas check them).
    sensor: Any = None
    object: Any = None
    model: Any = None
    classifier: Any = None
    mapping: Any = None
    eval: Any = None
    viz: Any = None
    task: Any = None
    dataset: Any = None

    def __post_init__(self) -> None:
        check_seed(self.seed)
        if len(self.materials) < 2:
            raise ValueError(f"materials={self.materials} needs at least two classes")
        if len(set(self.materials)) != len(self.materials):
            raise ValueError(f"materials={self.materials} has duplicates")
        if not (self.device in ("auto", "cpu", "cuda") or self.device.startswith("cuda:")):
            raise ValueError(f"device={self.device!r} must be auto, cpu, cuda or cuda:N")
        threads = str(self.threads)
        if threads != "auto" and not (threads.isdigit() and int(threads) >= 1):
            raise ValueError(f"threads={self.threads!r} must be auto or a whole number >= 1")


@dataclass
class TaskConfig:
    """A task is a function `run(cfg) -> dict` named by `_target_`."""

    _target_: str = "???"
    name: str = "???"


def register(cs) -> None:
    cs.store(group="schema", name="root", node=RootConfig)
    cs.store(group="schema/task", name="base", node=TaskConfig)
    register_experiments(cs)


@dataclass
class ClassifierExperimentConfig(TaskConfig):
    """task=classifier_experiment: sizes of the collected sets and the training budget."""

    samples_per_class_per_sensor: int = 300
    heldout_per_class_per_sensor: int = 50
    input_size: int = 224
    max_epochs: int = 100
    patience: int = 10

    def __post_init__(self) -> None:
        for key in (
            "samples_per_class_per_sensor",
            "heldout_per_class_per_sensor",
            "max_epochs",
            "patience",
        ):
            if getattr(self, key) < 1:
                raise ValueError(f"task.{key}={getattr(self, key)} must be >= 1")
        if not 32 <= self.input_size <= 512:
            raise ValueError(f"task.input_size={self.input_size} must be in 32..512")


def register_experiments(cs) -> None:
    cs.store(group="schema/task", name="classifier_experiment", node=ClassifierExperimentConfig)
