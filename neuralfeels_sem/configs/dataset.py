"""Schema for conf/dataset/: a tactile image folder `<root>/<sensor>/<material>/<id>.png`."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class TactileDatasetConfig:
    name: str = "tactile"
    # Relative paths: the working directory if they exist there, else the repository root.
    root: str = "data/tactile/sim"
    extensions: list[str] = field(default_factory=lambda: [".png", ".jpg", ".jpeg"])
    max_per_group: int | None = None  # cap images per (sensor, class), e.g. for a quick CPU run
    # task=train_classifier: a second set (e.g. simulated) mixed into training by
    # task.real_ratio; validation and test stay on root. null: root alone.
    sim_root: str | None = None

    def __post_init__(self) -> None:
        if not self.root:
            raise ValueError("dataset.root must name a folder")
        if self.max_per_group is not None and self.max_per_group < 1:
            raise ValueError(f"dataset.max_per_group={self.max_per_group} must be >= 1")


def register(cs) -> None:
    cs.store(group="schema/dataset", name="tactile", node=TactileDatasetConfig)
