"""The touches of frames the mapper did not take, mapped before the next one (realtime).

At sensor.pace=realtime the mapper takes the newest frame and the frames it overtook are
not mapped. Their tactile readings are the scarce source (a press lasts a few frames; the
camera's frames repeat each other), so the producer keeps the touches of up to
`mapping.overtaken_touch_frames` of them (pipeline/producer.py) and they ride with the next
frame to the mapper, as do those of a frame dropped for its lag. Each is placed with the
frame's own pose under `mapping.pose=gt`; with a tracked pose (the tracker estimates only
the frames mapped), with the pose interpolated in time between the mapped frames around
it. They get no optimiser steps of their own and their camera reading is not used.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.mapping.se3 import interpolate_pose
from neuralfeels_sem.pipeline.observers import tell_touches
from neuralfeels_sem.pipeline.pace import PerceivedFrame, in_contact


class OvertakenTouches:
    """Maps the touches that ride with a frame; `enabled` False: none are kept."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._carried: list[tuple[Frame, dict]] = []  # of frames dropped for their lag
        self._last: tuple[float, np.ndarray] | None = None  # the last mapped frame's time, pose

    def carry(self, item: PerceivedFrame) -> bool:
        """A frame dropped for its lag: its touches (and those it carried) go with the next
        frame mapped. True if its own readings are kept (not to be forgotten)."""
        if not self.enabled:
            return False
        self._carried += item.touches
        kept = in_contact(item.labels)
        if kept:
            self._carried.append((item.frame, item.labels))
        return kept

    def take(self, points, touches: list) -> list[tuple[Frame, dict, dict]]:
        """The touches riding with the next frame (carried ones first, oldest first), each
        with its contact depths read now from `points` (a PointExtractor): before the
        next frame's pose is estimated, which lets go of the older frames' percepts."""
        riding, self._carried = self._carried + list(touches), []
        return [(frame, labels, points.contact_depths(frame)) for frame, labels in riding]

    def add(self, session, riding: list, frame: Frame, world_T_object: np.ndarray) -> int:
        """Map the `riding` touches (`take`) before `frame`, which is mapped with
        `world_T_object`; how many frames' touches were mapped. `session`: the scorer,
        pose source, mapper and observers of a MappingSession."""
        own = session.pose_source.reads_frame_pose
        for touch_frame, labels, depths in riding:
            session.scorer.log_touches(touch_frame, labels)
            pose = (
                touch_frame.world_T_object
                if own
                else self._between(touch_frame, frame, world_T_object)
            )
            session.mapper.add_touches(touch_frame, labels, pose, depths)
            tell_touches(session.observers, touch_frame, labels, pose, session.mapper)
        self._last = (frame.time_s, world_T_object)
        return len(riding)

    def _between(self, touch_frame: Frame, frame: Frame, pose: np.ndarray) -> np.ndarray:
        """The pose interpolated in time between the last mapped frame's and `frame`'s."""
        if self._last is None:
            return pose
        start_s, start = self._last
        span = frame.time_s - start_s
        share = 1.0 if span <= 0 else float(np.clip((touch_frame.time_s - start_s) / span, 0, 1))
        return interpolate_pose(start, pose, share)
