"""The pose error of a tracked run: the average 3D error per frame (and its closest-point
form, for symmetric shapes) and its plot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from neuralfeels_sem.core.geometry import check_pose, invert_pose
from neuralfeels_sem.utils.atomic import atomic_write


def average_3d_error(
    world_T_est: np.ndarray, world_T_gt: np.ndarray, surface_points: np.ndarray
) -> float:
    """Mean distance (metres) between object surface points placed by the two poses."""
    check_pose(world_T_est, "world_T_est")
    check_pose(world_T_gt, "world_T_gt")
    diff = world_T_est - world_T_gt
    return float(np.linalg.norm(surface_points @ diff[:3, :3].T + diff[:3, 3], axis=1).mean())


def closest_point_error(
    world_T_est: np.ndarray,
    world_T_gt: np.ndarray,
    surface_points: np.ndarray,
    tree: cKDTree | None = None,
) -> float:
    """Mean distance (metres) from each surface point placed by the estimate to the nearest
    surface point placed by the truth: blind to motions a symmetric shape does not show
    (the spin of a body of revolution about its axis), which average_3d_error counts.

    Measured in the true object frame (distances do not change under a rigid motion), so
    `tree`, a cKDTree of `surface_points` built once, serves every frame.
    """
    check_pose(world_T_est, "world_T_est")
    check_pose(world_T_gt, "world_T_gt")
    gt_T_est = invert_pose(world_T_gt) @ world_T_est
    placed = surface_points @ gt_T_est[:3, :3].T + gt_T_est[:3, 3]
    return float((tree or cKDTree(surface_points)).query(placed)[0].mean())


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


class PoseErrorLog:
    """A tracked run's pose error against the ground truth, frame by frame.

    `sample_points()` (called on the first frame) gives surface samples of the true object;
    each frame records the average 3D error and its closest-point form (both mm).
    """

    def __init__(self, sample_points) -> None:
        self._sample_points = sample_points  # () -> (N, 3) object-frame surface points
        self._points: np.ndarray | None = None
        self._tree: cKDTree | None = None  # of _points, for the closest-point error
        self.curve: list[list[float]] = []  # [frame_index, time_s, error_mm]
        self.closest_mm: list[float] = []  # closest-point error of each row of `curve`

    def add(self, index: int, time_s: float, est: np.ndarray, gt: np.ndarray) -> None:
        if self._points is None:
            self._points = self._sample_points()
            self._tree = cKDTree(self._points)
        self.curve.append(
            [int(index), float(time_s), 1e3 * average_3d_error(est, gt, self._points)]
        )
        self.closest_mm.append(1e3 * closest_point_error(est, gt, self._points, self._tree))

    def metrics(self) -> dict:
        if not self.curve:
            return {}
        errors = np.array([row[2] for row in self.curve])
        out = {
            "pose_error_mm": float(errors.mean()),
            "pose_error_max_mm": float(errors.max()),
            "pose_error_final_mm": float(errors[-1]),
            "pose_error_curve": [list(row) for row in self.curve],
        }
        if len(self.closest_mm) == len(self.curve):  # a run resumed from before it had none
            out["pose_error_closest_mm"] = float(np.mean(self.closest_mm))
            out["pose_error_closest_final_mm"] = float(self.closest_mm[-1])
        return out

    def state(self) -> dict:
        return {"curve": [list(row) for row in self.curve], "closest_mm": list(self.closest_mm)}

    def load_state(self, state: dict) -> None:
        self.curve = [list(row) for row in state.get("curve", [])]
        self.closest_mm = [float(v) for v in state.get("closest_mm", [])]
