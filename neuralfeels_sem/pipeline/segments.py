"""A run resumed after a kill or an interrupt is a list of segments, one per process.

Each checkpoint carries the segments before it (in its `extra`), so a resumed run's
metrics.json covers the whole run: frames and wall time summed over the segments.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass
class Segment:
    """One process's share of a run: the frames it mapped, its wall time, sensor times."""

    first_frame: int = -1
    last_frame: int = -1
    frames: int = 0
    wall_s: float = 0.0
    first_time_s: float | None = None
    last_time_s: float | None = None
    partial: bool = False  # stopped by a signal (or a failed producer) before the last frame
    # sensor.pace=realtime (pipeline/pace.py): frames the mapper never took, the lag of
    # those it took (seconds since due), and steps run while no new frame had come.
    frames_dropped: int = 0
    lag_frames: int = 0
    lag_sum_s: float = 0.0
    lag_max_s: float | None = None
    idle_steps: int = 0
    # frames not mapped whose touches alone were (pipeline/touch_frames.py)
    touch_frames: int = 0
    # CPU seconds of the frame producer's thread and of the mapper's (the session's) over
    # the loop: the one busy for most of `wall_s` is what bounds the realtime factor.
    producer_cpu_s: float = 0.0
    mapper_cpu_s: float = 0.0
    # The producer's CPU seconds by stage (acquire, classify, perceive): which one to speed up.
    producer_stage_cpu_s: dict[str, float] = field(default_factory=dict)

    def add_lag(self, lag_s: float) -> None:
        self.lag_frames += 1
        self.lag_sum_s += lag_s
        self.lag_max_s = lag_s if self.lag_max_s is None else max(self.lag_max_s, lag_s)

    def record_producer(self, cpu_s: float, stage_cpu_s: dict[str, float]) -> None:
        self.producer_cpu_s, self.producer_stage_cpu_s = cpu_s, dict(stage_cpu_s)

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
    """Frames, wall time and sensor time of the whole run, its realtime factor, and (at
    sensor.pace=realtime) the frames dropped and the lag of the frames mapped."""
    frames = sum(s.frames for s in segments)
    lagged = [s for s in segments if s.lag_frames]
    lag_frames = sum(s.lag_frames for s in lagged)
    wall_s = sum(s.wall_s for s in segments)
    timed = [s for s in segments if s.first_time_s is not None]
    sensor_time_s = timed[-1].last_time_s - timed[0].first_time_s + frame_period_s if timed else 0.0
    return {
        "frames": frames,
        "wall_s": wall_s,
        "sensor_time_s": sensor_time_s,
        "realtime_factor": sensor_time_s / wall_s if wall_s > 0 else None,
        "frames_dropped": sum(s.frames_dropped for s in segments),
        "lag_max_s": max(s.lag_max_s for s in lagged) if lagged else None,
        "lag_mean_s": sum(s.lag_sum_s for s in lagged) / lag_frames if lagged else None,
        "idle_steps": sum(s.idle_steps for s in segments),
        "touch_frames": sum(s.touch_frames for s in segments),
        "producer_cpu_s": sum(s.producer_cpu_s for s in segments),
        "mapper_cpu_s": sum(s.mapper_cpu_s for s in segments),
        "producer_stage_cpu_s": _summed_stages(segments),
        "segments": [s.to_dict() for s in segments],
    }


def _summed_stages(segments: list[Segment]) -> dict[str, float]:
    totals: dict[str, float] = {}
    for segment in segments:
        for stage, seconds in segment.producer_stage_cpu_s.items():
            totals[stage] = totals.get(stage, 0.0) + seconds
    return totals
