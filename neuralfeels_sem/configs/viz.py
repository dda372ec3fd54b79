"""Schema for conf/viz/: which pictures a run writes (plain settings read by the task)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class VizConfig:
    # Write matching_curve.png, material_maps.png, progression.png and material_mesh.ply.
    plots: bool = True
    # Number of maps kept over the run for progression.png (evenly spread, last one included).
    progression_snapshots: int = 5
    dpi: int = 120

    def __post_init__(self) -> None:
        if self.progression_snapshots < 1:
            raise ValueError(f"viz.progression_snapshots={self.progression_snapshots} must be >= 1")
        if not 30 <= self.dpi <= 600:
            raise ValueError(f"viz.dpi={self.dpi} must be in 30..600")


def register(cs) -> None:
    cs.store(group="schema/viz", name="default", node=VizConfig)
