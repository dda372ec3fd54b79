"""The sensor's clock at sensor.pace=realtime, and the queue between producer and mapper.

Frame i is due at `i * frame_period_s` of wall time after the stream started: when the
segment's first frame was ready for the mapper (so the one-off set-up of the first frame,
models loading and renderers opening, is not counted as lag, as on a rig whose models load
before it streams; a resumed run starts on time too). A frame's lag is
how long ago it was due when the mapper takes it; one older than `mapping.max_lag_s` is
dropped. Every dropped frame is counted once, on the mapper's side, with the next frame it
takes (or at the end of the stream), so the counts of a checkpoint cover the frames it
holds.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from neuralfeels_sem.core.frame import Frame


class PaceClock:
    """Due times of a stream of `frame_period_s` starting at frame `first_index` now."""

    def __init__(self, frame_period_s: float, first_index: int) -> None:
        if frame_period_s <= 0:
            raise ValueError(f"frame_period_s={frame_period_s} must be > 0")
        self.frame_period_s = frame_period_s
        self.first_index = first_index
        self.start = time.monotonic()

    def restart(self) -> None:
        """The first frame is ready now: it is due now."""
        self.start = time.monotonic()

    def due_at(self, index: int) -> float:
        """The monotonic time at which frame `index` is due."""
        return self.start + (index - self.first_index) * self.frame_period_s

    def due_index(self) -> int:
        """The newest frame due now."""
        elapsed = time.monotonic() - self.start
        return self.first_index + max(0, math.floor(elapsed / self.frame_period_s))

    def lag(self, index: int) -> float:
        """Seconds since frame `index` was due (negative: not yet due)."""
        return time.monotonic() - self.due_at(index)


@dataclass
class PerceivedFrame:
    """A frame ready for the mapper: its touches classified and its perception done.

    `dropped_before`: frames dropped since the previous item the producer handed over.
    `touches`: (frame, labels) of earlier frames the mapper did not take, whose touches
    alone are to be mapped first, oldest first (sensor.pace=realtime).
    """

    frame: Frame
    labels: dict
    dropped_before: int = 0
    touches: list[tuple[Frame, dict]] = field(default_factory=list)


def in_contact(labels: dict) -> bool:
    """Whether any finger of a frame touched (its labels: finger -> TouchLabel)."""
    return any(label.contact for label in labels.values())


@dataclass
class StreamEnd:
    """The producer stopped: the sensor's last frame (`error` None) or its error."""

    dropped_before: int = 0
    error: BaseException | None = None


class FrameQueue:
    """A bounded queue of PerceivedFrames ending with one StreamEnd.

    `keep_newest` False (offline): `put` waits for room, so every frame reaches the mapper.
    `keep_newest` True (realtime): `put` never waits; a full queue lets go of its oldest
    frame (`on_drop` is told), whose count travels with the newer one. With `keep_touches`
    its touches travel too (and those it carried), to be mapped before the newer frame; only
    a frame let go without a touch is given to `on_drop`.
    """

    def __init__(
        self,
        capacity: int,
        keep_newest: bool,
        on_drop: Callable[[Frame], None] = lambda f: None,
        keep_touches: bool = False,
    ) -> None:
        if capacity < 1:
            raise ValueError(f"capacity={capacity} must be >= 1")
        self.capacity = capacity
        self.keep_newest = keep_newest
        self.on_drop = on_drop
        self.keep_touches = keep_touches
        self._items: deque = deque()
        self._ended = False
        self._cond = threading.Condition()

    def put(self, item: PerceivedFrame, stop: threading.Event) -> bool:
        """Add `item` (waiting for room when offline); False once `stop` is set."""
        with self._cond:
            while len(self._items) >= self.capacity and not self.keep_newest:
                if stop.is_set():
                    return False
                self._cond.wait(0.1)
            if len(self._items) >= self.capacity:
                old = self._items.popleft()
                item.dropped_before += old.dropped_before + 1
                keep = self.keep_touches and in_contact(old.labels)
                kept = [(old.frame, old.labels)] if keep else []
                item.touches[:0] = old.touches + kept
                if not kept:
                    self.on_drop(old.frame)
            self._items.append(item)
            self._cond.notify_all()
        return not stop.is_set()

    def end(self, end: StreamEnd) -> None:
        """The last item: nothing is put after it."""
        with self._cond:
            if not self._ended:
                self._ended = True
                self._items.append(end)
                self._cond.notify_all()

    def wait_empty(self, stop: threading.Event) -> None:
        """Until the mapper has taken every frame (or `stop` is set)."""
        with self._cond:
            while self._items and not stop.is_set():
                self._cond.wait(0.1)

    def ready(self) -> bool:
        """Whether an item is waiting."""
        with self._cond:
            return bool(self._items)

    def get(self, timeout: float) -> PerceivedFrame | StreamEnd | None:
        """The oldest item, waiting at most `timeout` seconds (None: nothing came)."""
        with self._cond:
            if not self._items:
                self._cond.wait(timeout)
            if not self._items:
                return None
            item = self._items.popleft()
            self._cond.notify_all()
            return item
