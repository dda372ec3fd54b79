"""What watches a mapping session from outside: a live viewer, a touch planner, a logger.

A session calls every observer after each frame it mapped (with the frame, the labels the
classifier gave its touches and the pose the frame was mapped at), after each scoring pass,
and once at the end. An observer that also defines `on_touches` (same arguments as
`on_frame`) hears of the touches of frames the mapper did not take, mapped before the next
frame at sensor.pace=realtime (pipeline/touch_frames.py): those frames are not mapped
frames, so `on_frame` is not called for them. Observers read the mapper; they never change
it, so a run with and without observers maps the same frames to the same field.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from neuralfeels_sem.core.frame import Frame


@runtime_checkable
class FrameObserver(Protocol):
    def on_frame(self, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper) -> None:
        """After `frame` was added to `mapper`; `labels`: finger -> TouchLabel
        (perception/touch.py: contact, class index or NO_LABEL, confidence, probabilities)."""

    def on_scores(self, frame_index: int, scores: dict | None, mapper) -> None:
        """After a scoring pass (`scores` None where the run has no ground truth)."""

    def close(self) -> None:
        """Once, after the last frame (also after an interrupted run)."""


def tell_touches(
    observers: list, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper
) -> None:
    """Call `on_touches` of the observers that define it (the optional hook above)."""
    for observer in observers:
        hook = getattr(observer, "on_touches", None)
        if hook is not None:
            hook(frame, labels, world_T_object, mapper)
