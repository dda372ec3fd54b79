"""The pose error of a tracked run: the average 3D error per frame and its plot."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from neuralfeels_sem.core.geometry import check_pose
from neuralfeels_sem.utils.atomic import atomic_write


def average_3d_error(
    world_T_est: np.ndarray, world_T_gt: np.ndarray, surface_points: np.ndarray
) -> float:
    """Mean distance (metres) between object surface points placed by the two poses."""
    check_pose(world_T_est, "world_T_est")
    check_pose(world_T_gt, "world_T_gt")
    diff = world_T_est - world_T_gt
    return float(np.linalg.norm(surface_points @ diff[:3, :3].T + diff[:3, 3], axis=1).mean())


def write_pose_error_plot(curve: list[list[float]], mode: str, path: Path, dpi: int) -> None:
    """pose_error.png: the error ([frame, time_s, error_mm] rows) over the run's time."""
    from matplotlib.figure import Figure

    rows = np.asarray(curve)
    fig = Figure(figsize=(6.0, 3.2))
    ax = fig.add_subplot()
    ax.plot(rows[:, 1], rows[:, 2], color="tab:blue", lw=1.5)
    ax.axhline(rows[:, 2].mean(), color="tab:gray", ls="--", lw=1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("average 3D pose error (mm)")
    ax.set_title(f"mapping.pose={mode}: mean {rows[:, 2].mean():.2f} mm")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_write(path, "wb") as f:
        fig.savefig(f, dpi=dpi, format="png")
