"""sensor=replay: yield the Frames of a recording (task=record layout or a FeelSight log).

`pace="offline"` yields as fast as the consumer takes frames (the default for mapping
and evaluation); `pace="realtime"` sleeps so frames come out at their recorded times.
A damaged frame is skipped with a warning and counted, or ends the run
(`on_damaged_frame`, damage.py).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.sensors.base import Sensor, check_pace
from neuralfeels_sem.sensors.hand_spec import hand_model_from_spec
from neuralfeels_sem.sensors.replay.damage import DAMAGE_POLICIES, DamagedFrame, DamageLog

log = logging.getLogger(__name__)


class ReplaySensor(Sensor):
    needs_object = False  # tasks may skip building the object for this sensor

    def __init__(
        self,
        recording: str | None = None,
        pace: str = "offline",
        format: str = "native",
        camera: str = "front-left",
        max_frames: int | None = None,
        name: str = "replay",
        obj: Any = None,
        class_names: Sequence[str] | None = None,
        on_damaged_frame: str = "skip",
    ) -> None:
        if format not in ("native", "feelsight"):
            raise ValueError(f"format={format!r} must be native or feelsight")
        if on_damaged_frame not in DAMAGE_POLICIES:
            raise ValueError(f"on_damaged_frame={on_damaged_frame!r} must be skip or stop")
        self.on_damaged_frame = on_damaged_frame
        self.damage: DamageLog | None = None
        self.recording = recording
        self.pace = check_pace(pace)
        self.format = format
        self.camera = camera
        self.max_frames = max_frames
        self.name = name
        self.obj = obj
        self.class_names = None if class_names is None else list(class_names)
        self._reader = None

    def open(self) -> None:
        self._reader = self.read_recording()
        path = self._reader.path
        self.frame_period_s = self._reader.frame_period_s
        self.damage = DamageLog(path, self.on_damaged_frame)
        self.damage.note_tail(self._reader.tail_dropped)
        log.info("replaying %d frames from %s (%s)", len(self), path, self.format)

    def read_recording(self):
        """The recording's reader (meta.json and frame records read, files not yet);
        one-line errors for a missing, empty or differently labelled recording."""
        if not self.recording:
            raise ConfigError("sensor=replay needs a recording: set sensor.recording=PATH")
        path = Path(self.recording).expanduser()
        if not path.is_dir():
            raise DataError(f"recording {path} not found: fix sensor.recording")
        if self.format == "feelsight":
            from neuralfeels_sem.sensors.replay.feelsight import FeelSightReader

            reader = FeelSightReader(path, camera=self.camera)
        else:
            from neuralfeels_sem.sensors.replay.recording import RecordingReader

            reader = RecordingReader(path)
        if len(reader) == 0:
            raise DataError(f"recording {path} holds no frames: record again or pick another")
        recorded = reader.class_names
        if self.class_names is not None and recorded is not None and recorded != self.class_names:
            raise ConfigError(
                f"recording {path} labels ground truth with materials={recorded}: run with the same materials"
            )
        return reader

    def __len__(self) -> int:
        if self._reader is None:
            return -1
        n = len(self._reader)
        return n if self.max_frames is None else min(n, self.max_frames)

    def frames(self) -> Iterator[Frame]:
        if self._reader is None:
            self.open()
        start_wall = time.monotonic()
        start_time = None
        for position in range(len(self)):
            try:
                frame = self._reader.frame(position)
            except DamagedFrame as damage:
                self.damage.add(damage)  # warns and counts, or stops the run in one line
                continue
            if self.pace == "realtime":
                start_time = frame.time_s if start_time is None else start_time
                delay = (frame.time_s - start_time) - (time.monotonic() - start_wall)
                if delay > 0:
                    time.sleep(delay)
            yield frame

    def hand_model(self) -> object | None:
        """The recording's hand model, for camera segmentation: the one a native
        recording names in meta.json, a FeelSight log's Allegro model; None if unknown."""
        if self._reader is None:
            self.open()
        if self.format == "feelsight":
            return self._reader.hand_model()
        return hand_model_from_spec(
            self._reader.meta.get("hand_model"), str(self._reader.path / "meta.json")
        )

    def damage_report(self) -> dict | None:
        """Frames skipped as damaged and records dropped from the end (metrics.json)."""
        return None if self.damage is None else self.damage.report()

    def close(self) -> None:
        self._reader = None
