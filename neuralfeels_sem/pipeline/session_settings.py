"""A mapping session's cadences, lag bound, checkpoint storage and helper threads."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SessionSettings:
    """From the config (eval.*, mapping.*, viz.*), where their defaults live; tasks/map.py
    fills it."""

    every_k_frames: int
    checkpoint_every: int  # 0: only the final checkpoint
    progression_snapshots: int
    max_lag_s: float  # read at sensor.pace=realtime
    checkpoint_storage: str  # mapping.checkpoint_storage (checkpoint_codec.py)
    acquire_thread: bool  # mapping.acquire_thread (producer.py)
    helper_nice: int  # mapping.helper_nice (utils/thread_priority.py), read at sensor.pace=offline
    overtaken_touch_frames: int  # mapping.overtaken_touch_frames (touch_frames.py), realtime

    def nice_at(self, pace: str) -> int:
        return helper_nice_at(self.helper_nice, pace)


def helper_nice_at(helper_nice: int, pace: str) -> int:
    """What the helper threads (and a sensor's own process) add to their nice value at this
    pace: at realtime the producer keeps the sensor's clock and takes its share of the cores."""
    return helper_nice if pace == "offline" else 0
