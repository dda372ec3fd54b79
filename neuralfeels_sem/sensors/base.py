"""Sensor backends: an iterable of Frames with an explicit open/close lifecycle.

Constructors only store configuration (cheap, no I/O) so that every config can be
instantiated in tests; `open()` connects to devices or builds the simulator.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator

from neuralfeels_sem.core.frame import Frame


class Sensor(ABC):
    """A source of Frames (sim, real hardware or a recording)."""

    #: sensor time between frames, seconds
    frame_period_s: float = 0.1

    def open(self) -> None:  # noqa: B027 - optional hook
        """Connect / build; raise HardwareError or DataError with a one-line fix."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release devices; safe to call twice."""

    @abstractmethod
    def frames(self) -> Iterator[Frame]:
        """Yield frames until the configured duration or the end of the data."""

    def __len__(self) -> int:
        """Number of frames this sensor will yield (for progress bars); -1 if unknown."""
        return -1

    def __enter__(self) -> Sensor:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()
