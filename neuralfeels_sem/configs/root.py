"""Schema for the top-level keys of conf/config.yaml and for conf/task/."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

DEFAULT_MATERIALS = ["plastic", "metal", "fabric", "wood"]


@dataclass
class RootConfig:
    seed: int = 0
    materials: list[str] = field(default_factory=lambda: list(DEFAULT_MATERIALS))
    device: str = "auto"  # auto | cpu | cuda | cuda:N
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
        if self.seed < 0:
            raise ValueError(f"seed={self.seed} must be >= 0")
        if len(self.materials) < 2:
            raise ValueError(f"materials={self.materials} needs at least two classes")
        if len(set(self.materials)) != len(self.materials):
            raise ValueError(f"materials={self.materials} has duplicates")
        if not (self.device in ("auto", "cpu", "cuda") or self.device.startswith("cuda:")):
            raise ValueError(f"device={self.device!r} must be auto, cpu, cuda or cuda:N")


@dataclass
class TaskConfig:
    """A task is a function `run(cfg) -> dict` named by `_target_`."""

    _target_: str = "???"
    name: str = "???"


def register(cs) -> None:
    cs.store(group="schema", name="root", node=RootConfig)
    cs.store(group="schema/task", name="base", node=TaskConfig)
