"""What a tracked run counts frame by frame (pose_source.TrackedPose), kept as plain
values so that a checkpoint stores them as they are and a resumed run counts on."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields


@dataclass
class TrackingCounts:
    """The frames a tracked run kept, retried, re-localised, and its fit and time."""

    kept: dict[str, int] = field(default_factory=dict)  # why frames were not tracked, how often
    fit_curve: list[list[float]] = field(default_factory=list)  # [frame, share, conditioning]
    tracked_frames: int = 0
    reinitialised_frames: int = 0  # tracked only after a restart from the last pose
    relocalised_frames: int = 0  # tracked only after re-localisation (relocalise.py)
    degenerate_frames: int = 0  # tracked, some directions held by the motion prior
    recent_shares: list[float] = field(default_factory=list)  # of the last tracked frames
    kept_in_a_row: int = 0  # frames not tracked since the last tracked one
    colourless_frames: int = 0  # solved with colour on but no earlier view to compare
    track_seconds: float = 0.0  # wall time spent tracking (SDF evaluations dominate)

    def state(self) -> dict:
        return {f.name: copy.deepcopy(getattr(self, f.name)) for f in fields(self)}

    def load_state(self, state: dict) -> None:
        """Restore what `state` holds; a count a checkpoint lacks starts from zero."""
        fresh = TrackingCounts()
        for f in fields(self):
            default = getattr(fresh, f.name)
            value = copy.deepcopy(state.get(f.name, default))
            setattr(
                self, f.name, type(default)(value) if isinstance(default, float | int) else value
            )
        self.kept = {str(k): int(v) for k, v in self.kept.items()}
