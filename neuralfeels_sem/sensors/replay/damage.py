"""Damaged frames of a recording or FeelSight log: report each, then skip it or stop.

A frame is damaged when its line in frames.jsonl is not valid JSON or lacks a key, or
when one of its files is missing or unreadable. With `on_damaged_frame=skip` (the
default) the replay warns once per damaged frame, skips it and counts it (metrics.json's
`replay` block); with `stop` the run ends with one line naming the frame and the file.
Records missing at the very end of a recording are not damage: a recorder stopped
mid-write leaves them, and the readers drop that tail (reported once, in `tail_dropped`).
"""

from __future__ import annotations

import logging
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from neuralfeels_sem.core.errors import DataError

log = logging.getLogger(__name__)

DAMAGE_POLICIES = ("skip", "stop")
# metrics.json lists this many damaged frames; the count covers them all.
LISTED_DAMAGE = 20
# What numpy, OpenCV and our parsers raise on a missing, truncated or malformed file.
READ_ERRORS = (OSError, ValueError, EOFError, KeyError, TypeError, zipfile.BadZipFile)

T = TypeVar("T")


class DamagedFrame(DataError):
    """One frame cannot be read: its index, the file at fault and why."""

    def __init__(self, index: int, file: str, why: str) -> None:
        super().__init__(f"frame {index}: {file} {why}")
        self.index = index
        self.file = file
        self.why = why


def read_or_damaged(index: int, path: Path, root: Path, read: Callable[[Path], T]) -> T:
    """`read(path)`, or DamagedFrame naming the frame and `path` (relative to `root`)."""
    name = str(path.relative_to(root)) if path.is_relative_to(root) else str(path)
    if not path.is_file():
        raise DamagedFrame(index, name, "is missing")
    try:
        value = read(path)
    except READ_ERRORS as exc:
        raise DamagedFrame(index, name, f"is unreadable ({type(exc).__name__})") from exc
    if value is None:  # cv2.imread's answer for a file it cannot decode
        raise DamagedFrame(index, name, "is unreadable (not a valid image)")
    return value


class DamageLog:
    """The damaged frames of one replay, and what to do about each."""

    def __init__(self, recording: Path, policy: str = "skip") -> None:
        if policy not in DAMAGE_POLICIES:
            raise ValueError(f"on_damaged_frame={policy!r} must be skip or stop")
        self.recording = recording
        self.policy = policy
        self.frames_skipped = 0
        self.damaged: list[dict] = []
        self.tail_dropped = 0

    def add(self, damage: DamagedFrame) -> None:
        """Warn and count the frame, or (policy stop) raise DataError in one line."""
        if self.policy == "stop":
            raise DataError(
                f"recording {self.recording}: {damage}; repair or remove it, "
                "or set sensor.on_damaged_frame=skip to replay the other frames"
            )
        log.warning("recording %s: skipping damaged %s", self.recording, damage)
        self.frames_skipped += 1
        if len(self.damaged) < LISTED_DAMAGE:
            self.damaged.append({"index": damage.index, "file": damage.file, "why": damage.why})

    def note_tail(self, count: int) -> None:
        """Records dropped from the end (a recorder stopped mid-write): one warning."""
        self.tail_dropped = count
        if count:
            log.warning(
                "recording %s: its last %d record(s) are incomplete (recording stopped "
                "mid-write); replaying the frames before them",
                self.recording,
                count,
            )

    def report(self) -> dict:
        """metrics.json's `replay` block."""
        return {
            "frames_skipped": self.frames_skipped,
            "damaged": self.damaged,
            "tail_dropped": self.tail_dropped,
            "on_damaged_frame": self.policy,
        }
