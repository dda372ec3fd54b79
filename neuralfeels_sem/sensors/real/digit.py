"""DIGIT tactile sensors through digit-interface (or a video file standing in for one).

A DIGIT streams QVGA (320 x 240) at 60 fps or 30 fps, or VGA (640 x 480) at 30 or 15 fps,
as a landscape image; `digit_raw_to_image` turns it into the project's portrait DIGIT image
(320 rows x 240 columns, RGB), the same rotation digit-interface applies in `get_frame()`.
At open each sensor captures `background_frames` frames without contact and keeps their
per-pixel median as the background for the contact gate.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_WIDTH
from neuralfeels_sem.core.errors import DataError, HardwareError
from neuralfeels_sem.core.hand import FINGERS

log = logging.getLogger(__name__)

# Stream modes digit-interface supports: resolution -> allowed frame rates.
STREAMS = {"QVGA": (60, 30), "VGA": (30, 15)}


def digit_raw_to_image(raw_bgr: np.ndarray) -> np.ndarray:
    """One landscape DIGIT stream frame (BGR) -> (320, 240, 3) RGB uint8, sensor orientation."""
    if raw_bgr.ndim != 3 or raw_bgr.shape[2] != 3:
        raise ValueError(f"DIGIT frame must be (H, W, 3), got {raw_bgr.shape}")
    image = cv2.flip(cv2.transpose(raw_bgr), 0)
    if image.shape[:2] != (DIGIT_HEIGHT, DIGIT_WIDTH):
        image = cv2.resize(image, (DIGIT_WIDTH, DIGIT_HEIGHT), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


class DigitCamera:
    """One DIGIT by serial, or a video file of raw DIGIT frames when `video_file` is set."""

    def __init__(
        self,
        finger: str,
        serial: str = "",
        resolution: str = "QVGA",
        fps: int = 60,
        background_frames: int = 10,
        video_file: str | None = None,
    ) -> None:
        if finger not in FINGERS:
            raise ValueError(f"unknown finger {finger!r}; expected one of {FINGERS}")
        if resolution not in STREAMS or fps not in STREAMS[resolution]:
            raise ValueError(f"DIGIT stream {resolution}@{fps} unsupported; choose from {STREAMS}")
        if background_frames < 1:
            raise ValueError(f"background_frames={background_frames} must be >= 1")
        self.finger = finger
        self.serial = serial
        self.resolution = resolution
        self.fps = fps
        self.background_frames = background_frames
        self.video_file = video_file
        self.background: np.ndarray | None = None
        self._digit = None
        self._capture: cv2.VideoCapture | None = None

    @property
    def name(self) -> str:
        source = (
            f"video {self.video_file}" if self.video_file else f"serial {self.serial or 'unset'}"
        )
        return f"DIGIT {self.finger} ({source})"

    def open(self) -> None:
        if self.video_file:
            self._capture = cv2.VideoCapture(self.video_file)
            if not self._capture.isOpened():
                self._capture = None
                raise DataError(
                    f"{self.name}: cannot open the video: fix sensor.digit.video_files.{self.finger}"
                )
        else:
            self._open_device()
        frames = [self.read() for _ in range(self.background_frames)]
        self.background = np.median(np.stack(frames), axis=0).round().astype(np.uint8)

    def _open_device(self) -> None:
        from digit_interface import Digit, DigitHandler

        found = DigitHandler.list_digits()
        serials = [d["serial"] for d in found]
        hint = f"connected DIGITs: {', '.join(serials) if serials else 'none'}"
        if not self.serial:
            raise HardwareError(
                f"DIGIT {self.finger}: no serial configured ({hint}): set sensor.digit.serials.{self.finger}"
            )
        if self.serial not in serials:
            raise HardwareError(
                f"DIGIT {self.finger} (serial {self.serial}) not found ({hint}): "
                f"connect it or set sensor.digit.serials.{self.finger}"
            )
        digit = Digit(self.serial, name=self.finger)
        try:
            digit.connect()
            digit.set_resolution(Digit.STREAMS[self.resolution])
            digit.set_fps(self.fps)
        except Exception as exc:  # digit-interface raises bare Exception on a busy / broken device
            raise HardwareError(
                f"{self.name}: cannot start the stream ({exc}): is another program using it?"
            ) from exc
        self._digit = digit

    def read_raw(self) -> np.ndarray:
        """Next landscape BGR stream frame; HardwareError when the sensor stopped answering."""
        if self._capture is not None:
            ok, raw = self._capture.read()
            if not ok:
                raise HardwareError(f"{self.name}: no more frames")
            return raw
        if self._digit is None:
            raise RuntimeError(f"{self.name} is not open")
        try:
            return self._digit.get_frame(transpose=True)
        except Exception as exc:  # digit-interface raises bare Exception when a grab fails
            raise HardwareError(f"{self.name}: frame grab failed ({exc})") from exc

    def read(self) -> np.ndarray:
        """Next frame as a (320, 240, 3) RGB DIGIT image."""
        return digit_raw_to_image(self.read_raw())

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None
        if self._digit is not None:
            try:
                self._digit.disconnect()
            finally:
                self._digit = None


class DigitArray:
    """The hand's DIGITs: `fingers` in use, each with a serial (or a video file standing in)."""

    def __init__(
        self,
        serials: Mapping[str, str],
        fingers: Sequence[str] = FINGERS,
        resolution: str = "QVGA",
        fps: int = 60,
        background_frames: int = 10,
        video_files: Mapping[str, str] | None = None,
    ) -> None:
        unknown = set(fingers) - set(FINGERS)
        if unknown:
            raise ValueError(f"unknown fingers {sorted(unknown)}; expected a subset of {FINGERS}")
        video_files = dict(video_files or {})
        self.cameras = [
            DigitCamera(
                f, serials.get(f, ""), resolution, fps, background_frames, video_files.get(f)
            )
            for f in FINGERS
            if f in fingers
        ]
