"""Where the object pose used for mapping comes from (`mapping.pose`).

`gt` takes the frame's pose (the simulator's, or markers on hardware): the paper's
setting. The tracking modes estimate it (see pose tracking in the README). Every source
also reports how its pose relates to the ground truth, so a run in tracked mode is
scored the way a user without ground truth would see it.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.sensors.frame import Frame
from neuralfeels_sem.utils.geometry import invert_pose


class PoseSource:
    """Pose per frame for the mapper; `gt` behaviour (the frame's own pose)."""

    name = "gt"

    def estimate(self, frame: Frame, mapper) -> np.ndarray:
        """world_T_object to map this frame with."""
        self.last_estimate = frame.world_T_object
        self.last_frame = frame
        return frame.world_T_object

    def field_T_gt_object(self) -> np.ndarray:
        """Maps ground-truth object-frame points into the field's frame at the last frame.

        Identity when the mapping pose is the ground truth; with a tracked pose it carries
        the tracking error, so matching and shape scores include it.
        """
        frame = getattr(self, "last_frame", None)
        if frame is None or frame.gt_world_T_object is None:
            return np.eye(4)
        return invert_pose(self.last_estimate) @ frame.gt_world_T_object

    def metrics(self) -> dict:
        """Pose-error figures for metrics.json (none for the ground-truth pose)."""
        return {}

    def write_pictures(self, out_dir, dpi: int) -> None:
        """Pose-error plot (pose_error.png) for tracking sources; nothing for `gt`."""

    def state(self) -> dict:
        return {}

    def load_state(self, state: dict) -> None:
        pass


def build_pose_source(pose: str, obj=None) -> PoseSource:
    """The pose source named by `mapping.pose`."""
    from neuralfeels_sem.mapping.mapper import resolve_pose_source

    resolve_pose_source(pose)
    return PoseSource()
