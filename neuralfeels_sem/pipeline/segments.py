"""A run resumed after a kill or an interrupt is a list of segments, one per process.

Each checkpoint carries the segments before it (in its `extra`), so a resumed run's
metrics.json covers the whole run: frames and wall time summed over the segments.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass
class Segment:
    """One process's share of a run: the frames it mapped, its wall time, sensor times."""

    first_frame: int = -1
    last_frame: int = -1
    frames: int = 0
    wall_s: float = 0.0
    first_time_s: float | None = None
    last_time_s: float | None = None
    partial: bool = False  # stopped by a signal before the sensor's last frame

    def add_frame(self, index: int, time_s: float) -> None:
        if self.first_time_s is None:
            self.first_frame, self.first_time_s = index, time_s
        self.last_frame, self.last_time_s = index, time_s
        self.frames += 1

    def to_dict(self) -> dict:
        return asdict(self)


def load_segments(records: list[dict]) -> list[Segment]:
    return [Segment(**record) for record in records]


def run_totals(segments: list[Segment], frame_period_s: float) -> dict:
    """Frames, wall time and sensor time of the whole run, and its realtime factor."""
    frames = sum(s.frames for s in segments)
    wall_s = sum(s.wall_s for s in segments)
    timed = [s for s in segments if s.first_time_s is not None]
    sensor_time_s = timed[-1].last_time_s - timed[0].first_time_s + frame_period_s if timed else 0.0
    return {
        "frames": frames,
        "wall_s": wall_s,
        "sensor_time_s": sensor_time_s,
        "realtime_factor": sensor_time_s / wall_s if wall_s > 0 else None,
        "segments": [s.to_dict() for s in segments],
    }
