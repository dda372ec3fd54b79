"""Sensor backends: an iterable of Frames with an explicit open/close lifecycle.

Constructors only store configuration (cheap, no I/O) so that every config can be
instantiated in tests; `open()` connects to devices or builds the simulator.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator

from neuralfeels_sem.core.frame import Frame

# sensor.pace: offline maps every frame, however long that takes; realtime streams at the
# sensor's own clock and the mapper takes the newest frame (pipeline/producer.py).
PACES = ("offline", "realtime")


def check_pace(pace: str) -> str:
    if pace not in PACES:
        raise ValueError(f"sensor.pace={pace!r}: use one of {', '.join(PACES)}")
    return pace


class Sensor(ABC):
    """A source of Frames (sim, real hardware or a recording)."""

    #: sensor time between frames, seconds
    frame_period_s: float = 0.1
    #: offline | realtime (PACES): how a mapping run consumes this sensor's frames
    pace: str = "offline"

    def open(self) -> None:  # noqa: B027 - optional hook
        """Connect / build; raise HardwareError or DataError with a one-line fix."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release devices; safe to call twice."""

    @abstractmethod
    def frames(self) -> Iterator[Frame]:
        """Yield frames until the configured duration or the end of the data."""

    def frames_from_clock(
        self, due_index: Callable[[], int], touch_frames: int = 0
    ) -> Iterator[Frame]:
        """Frames at the sensor's own clock: `due_index()` is the newest frame the world has
        reached now; a frame overtaken by a newer due one is not yielded, except that the
        last `touch_frames` overtaken before each yielded frame come first, marked
        `touches_only` and without their camera reading (their touches are kept).

        This default reads every frame and skips the overtaken ones; a sensor that can go
        straight to a frame (the simulator) overrides it and never makes them.
        """
        for frame in self.frames():
            due = due_index()
            if frame.index >= due:
                yield frame
            elif touch_frames > 0 and frame.index >= due - touch_frames and frame.tactile:
                yield dataclasses.replace(frame, camera=None, touches_only=True)

    def hand_model(self) -> object | None:
        """The hand's kinematic model for camera segmentation, or None when unknown.

        An object with `world_T_palm` (4x4), `joint_limits` (J, 2) and `link_meshes(q)`
        -> [(trimesh, world_T_mesh)] (perception/camera_segmentation.py HandModel); a model
        without `link_meshes` (no meshes) lets segmentation skip the hand step.
        """
        return None

    def damage_report(self) -> dict | None:
        """Damaged input frames skipped so far (a replay's; metrics.json), None if none can be."""
        return None

    def __len__(self) -> int:
        """Number of frames this sensor will yield (for progress bars); -1 if unknown."""
        return -1

    def __enter__(self) -> Sensor:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class IndexedSensor(Sensor):
    """A sensor that can make any frame by its index (the simulator, a sensor in a process
    of its own): at realtime pace it goes straight to the due frame and never makes the
    frames it overtook, except the touches asked for."""

    @abstractmethod
    def frame_at(self, index: int, touches_only: bool = False) -> Frame:
        """Frame `index` (non-decreasing indices); `touches_only`: its DIGIT readings
        without the camera's (Frame.touches_only)."""

    def frames(self) -> Iterator[Frame]:
        self.open()
        for index in range(len(self)):
            yield self.frame_at(index)

    def frames_from_clock(
        self, due_index: Callable[[], int], touch_frames: int = 0
    ) -> Iterator[Frame]:
        """Only the newest due frame is made, after the DIGITs alone of the last
        `touch_frames` frames it overtook (Sensor.frames_from_clock); the other overtaken
        frames are never made."""
        self.open()
        index = None
        while (due := due_index() if index is None else max(index, due_index())) < len(self):
            if index is not None:
                for overtaken in range(max(index, due - touch_frames), due):
                    yield self.frame_at(overtaken, touches_only=True)
            yield self.frame_at(due)
            index = due + 1
