"""DIGIT device: stream orientation, background capture from a video through OpenCV, missing devices."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.errors import DataError, HardwareError
from neuralfeels_sem.sensors.real.digit import DigitArray, DigitCamera, digit_raw_to_image
from tests.sensors.real.video_digits import digit_like_frames, write_video


def test_raw_frame_rotates_like_digit_interface() -> None:
    raw = np.zeros((240, 320, 3), np.uint8)
    raw[0, 0] = (255, 0, 0)  # blue in BGR, top-left of the landscape stream
    raw[0, 319] = (0, 0, 255)  # red, top-right
    image = digit_raw_to_image(raw)
    assert image.shape == (320, 240, 3)
    # transpose then vertical flip: (r, c) -> (W-1-c, r)
    assert tuple(image[319, 0]) == (0, 0, 255)  # blue, now RGB
    assert tuple(image[0, 0]) == (255, 0, 0)
    vga = digit_raw_to_image(np.full((480, 640, 3), 7, np.uint8))
    assert vga.shape == (320, 240, 3) and vga.max() == 7


def test_background_is_the_median_of_the_first_frames_of_a_video(tmp_path) -> None:
    frames = digit_like_frames(12)
    video = write_video(tmp_path / "index.avi", frames)
    camera = DigitCamera("index", video_file=str(video), background_frames=5)
    camera.open()
    try:
        expected = np.median(np.stack([digit_raw_to_image(f) for f in frames[:5]]), axis=0)
        assert camera.background.shape == (320, 240, 3) and camera.background.dtype == np.uint8
        assert np.abs(camera.background.astype(float) - expected).mean() < 3.0  # MJPG is lossy
        sixth = camera.read()
        assert np.abs(sixth.astype(float) - digit_raw_to_image(frames[5])).mean() < 3.0
        for _ in range(6):
            camera.read()
        with pytest.raises(HardwareError, match="no more frames"):
            camera.read()
    finally:
        camera.close()


def test_missing_digit_names_serial_and_config_key() -> None:
    # No DIGIT is attached to a test machine: digit-interface's udev scan finds none.
    with pytest.raises(HardwareError) as info:
        DigitCamera("middle", serial="D20001").open()
    message = str(info.value)
    assert "DIGIT middle (serial D20001) not found" in message
    assert "sensor.digit.serials.middle" in message and "\n" not in message
    with pytest.raises(HardwareError, match="no serial configured"):
        DigitCamera("thumb").open()


def test_bad_video_and_bad_stream_settings() -> None:
    with pytest.raises(DataError, match="video_files.ring"):
        DigitCamera("ring", video_file="/nonexistent.avi").open()
    with pytest.raises(ValueError):
        DigitCamera("ring", resolution="VGA", fps=60)


def test_array_keeps_finger_order_and_video_overrides() -> None:
    with pytest.raises(ValueError, match="pinky"):
        DigitArray(serials={}, fingers=["pinky"])
    array = DigitArray(
        serials={"thumb": "D1", "index": "D2", "middle": "D3"},
        fingers=["thumb", "ring", "index"],
        video_files={"ring": "r.avi"},
    )
    assert [(c.finger, c.serial, c.video_file) for c in array.cameras] == [
        ("index", "D2", None),
        ("ring", "", "r.avi"),
        ("thumb", "D1", None),
    ]
