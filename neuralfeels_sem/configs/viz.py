"""Schema for conf/viz/: which pictures a run writes and its live view (plain settings
read by the task; the live view: viz/live.py)."""

from __future__ import annotations

from dataclasses import dataclass

from neuralfeels_sem.viz.live import LIVE_VIEWERS


@dataclass
class VizConfig:
    # Write matching_curve.png, material_maps.png, progression.png and material_mesh.ply.
    plots: bool = True
    # Number of maps kept over the run for progression.png (evenly spread, last one included).
    progression_snapshots: int = 5
    dpi: int = 120
    # Live view of a map run: none, or rerun (streams to live.rrd in the run directory;
    # needs the optional extra: pip install -e .[live]); viz/live.py LIVE_VIEWERS.
    live: str = "none"
    live_spawn: bool = False  # also start a rerun viewer (needs a display)
    live_mesh_resolution: int = 64  # grid of the mesh streamed at each scoring pass
    live_camera_points: int = 10000  # camera points streamed per frame, at most

    def __post_init__(self) -> None:
        if self.progression_snapshots < 1:
            raise ValueError(f"viz.progression_snapshots={self.progression_snapshots} must be >= 1")
        if not 30 <= self.dpi <= 600:
            raise ValueError(f"viz.dpi={self.dpi} must be in 30..600")
        if self.live not in LIVE_VIEWERS:
            raise ValueError(f"viz.live={self.live} must be one of {', '.join(LIVE_VIEWERS)}")
        if not 16 <= self.live_mesh_resolution <= 512:
            raise ValueError(
                f"viz.live_mesh_resolution={self.live_mesh_resolution} must be in 16..512"
            )
        if self.live_camera_points < 1:
            raise ValueError(f"viz.live_camera_points={self.live_camera_points} must be >= 1")


def register(cs) -> None:
    cs.store(group="schema/viz", name="default", node=VizConfig)
