"""The mapper's counters: what the field actually learned from (metrics.json `trained_on`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from neuralfeels_sem.mapping.touch_memory import TouchBuffer


@dataclass
class TrainingLog:
    """Counts since the start of the run (a resumed run continues them)."""

    frames_seen: int = 0
    steps: int = 0  # optimiser steps
    warmed_up: bool = False  # the warm-up steps ran (on the first frame with data)
    camera_points_total: int = 0  # camera points stored in keyframes
    tactile_points_total: int = 0  # contact points stored in touches

    def trained_on(self, touches: TouchBuffer) -> dict:
        """See docs/design.md: metrics.json `trained_on`."""
        return {
            "frames": self.frames_seen,
            "camera_points": self.camera_points_total,
            "tactile_points": self.tactile_points_total,
            "touches": touches.num_touches,
            "labelled_touches": touches.num_labelled,
            "fused_touches": touches.num_fused,
            "outvoted_touches": touches.num_outvoted,
            "optimizer_steps": self.steps,
        }

    def state_dict(self) -> dict:
        return asdict(self)

    def load_state_dict(self, state: dict) -> None:
        self.frames_seen = int(state["frames_seen"])
        self.steps = int(state["steps"])
        self.warmed_up = bool(state["warmed_up"])
        self.camera_points_total = int(state["camera_points_total"])
        self.tactile_points_total = int(state["tactile_points_total"])
