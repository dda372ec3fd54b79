"""Starting poses for re-localising a frame whose tracking solves did not fit.

A smooth, partly hidden view leaves a wide valley in the SDF cost, e.g. the spin of a
long round handle about its own axis; when the motion changes (the hand turns the object
about another axis) a solve from the prediction, or from the last pose, can slide into a
wrong basin. Solving again from the last pose turned a little either way about each
object axis puts some start on the other side of that valley; the tracker keeps the
solve that fits its frame best (pose_source.py).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from neuralfeels_sem.core.geometry import check_pose, invert_pose
from neuralfeels_sem.mapping.se3 import se3_exp

Solve = Callable[[np.ndarray], tuple[np.ndarray, dict]]  # start pose -> (pose, tracker info)


def turned_starts(
    world_T_object: np.ndarray, centre_object: np.ndarray, degrees: float
) -> list[np.ndarray]:
    """world_T_object turned by +-degrees about each object-frame axis through
    `centre_object` (object frame, e.g. the centroid of the frame's points): 6 poses."""
    check_pose(world_T_object, "world_T_object")
    centre = np.asarray(centre_object, dtype=np.float64)
    if centre.shape != (3,) or not np.isfinite(centre).all():
        raise ValueError(f"centre_object must be a finite (3,) point, got {centre}")
    if not 0 < degrees < 90:
        raise ValueError(f"degrees={degrees} must be in (0, 90)")
    starts = []
    for axis in np.eye(3):
        for sign in (1.0, -1.0):
            turn = se3_exp(np.concatenate([np.zeros(3), sign * np.radians(degrees) * axis]))
            turn[:3, 3] = centre - turn[:3, :3] @ centre  # about the centre, not the origin
            starts.append(world_T_object @ turn)
    return starts


def relocalise(
    solve: Solve, last: np.ndarray, points: Mapping[str, np.ndarray], degrees: float
) -> tuple[np.ndarray, dict] | None:
    """The passing solve with the highest inlier share from `last` turned about each object
    axis through the centroid of the frame's world points; None when none passes."""
    world = np.concatenate([np.asarray(p).reshape(-1, 3) for p in points.values()])
    world = world[np.isfinite(world).all(axis=1)]
    if not len(world):
        return None
    centre = (invert_pose(last) @ np.append(world.mean(axis=0), 1.0))[:3]
    best = None
    for init in turned_starts(last, centre, degrees):
        pose, info = solve(init)
        if not info["skipped"] and (best is None or info["inlier_share"] > best[1]["inlier_share"]):
            best = (pose, info)
    return best
