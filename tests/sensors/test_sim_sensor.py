"""sensor=sim yields consistent Frames: contact shows only where the ground truth says so."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_INTRINSICS, DIGIT_WIDTH
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sensors.sim import SimSensor
from tests.sim.shapes import CLASSES, two_material_sphere


@pytest.fixture(scope="module")
def frames():
    sensor = SimSensor(two_material_sphere(), class_names=CLASSES, duration_s=0.6, fps=10.0, seed=0)
    with sensor:
        out = list(sensor.frames())
    return sensor, out


def test_yields_the_configured_frames_with_consistent_shapes(frames) -> None:
    sensor, out = frames
    assert len(sensor) == 6 and len(out) == 6
    for i, frame in enumerate(out):
        assert frame.index == i and frame.time_s == pytest.approx(i / 10.0)
        np.testing.assert_allclose(frame.world_T_object, frame.gt_world_T_object)
        assert frame.joint_positions.shape == (16,)
        assert set(frame.tactile) == set(FINGERS)
        for reading in frame.tactile.values():
            assert reading.image.shape == (DIGIT_HEIGHT, DIGIT_WIDTH, 3)
            assert reading.background.shape == (DIGIT_HEIGHT, DIGIT_WIDTH, 3)
            assert (
                reading.gt_depth.shape
                == reading.gt_contact_mask.shape
                == (DIGIT_HEIGHT, DIGIT_WIDTH)
            )
            assert reading.intrinsics == DIGIT_INTRINSICS
        cam = frame.camera
        assert cam.rgb.shape == (240, 320, 3) and cam.depth.shape == (240, 320)
        assert cam.mask.any()  # the object is in view
    # The object turns between frames.
    assert not np.allclose(out[0].world_T_object[:3, :3], out[-1].world_T_object[:3, :3])


def test_contact_shows_on_touching_fingers_only(frames) -> None:
    _, out = frames
    touched = untouched = 0
    for frame in out:
        for reading in frame.tactile.values():
            diff = np.abs(reading.image.astype(np.float32) - reading.background).mean(axis=2)
            mask = reading.gt_contact_mask
            if mask.sum() > 200:
                touched += 1
                assert diff[mask].mean() > 3.0 * diff[~mask].mean()  # contact stands out from noise
                assert np.all(reading.gt_depth[mask] > 0) and np.all(reading.gt_depth[~mask] == 0)
                labels = set(np.unique(reading.gt_material[mask]).tolist())
                assert labels <= {CLASSES.index("metal"), CLASSES.index("fabric")}
            elif not mask.any():
                untouched += 1
                assert diff.mean() < 3.0  # only pixel noise (std 2)
    assert touched >= 6  # most of 6 frames x 4 fingers touch
    assert touched + untouched >= 20


def test_finger_subset_and_no_camera() -> None:
    sensor = SimSensor(
        two_material_sphere(), duration_s=0.2, fps=10.0, fingers=["index", "thumb"], camera=False
    )
    with sensor:
        out = list(sensor.frames())
    assert len(out) == 2
    for frame in out:
        assert frame.camera is None
        assert set(frame.tactile) == {"index", "thumb"}


def test_missing_object_or_wrong_classes_is_one_line_config_error() -> None:
    with pytest.raises(ConfigError, match="object=") as info:
        SimSensor(None).open()
    assert "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="materials"):
        SimSensor(two_material_sphere(), class_names=["wood", "metal"]).open()


def test_constructor_is_cheap_and_checks_arguments() -> None:
    sensor = SimSensor(two_material_sphere(), duration_s=2.5, fps=4.0)
    assert sensor.rig is None and len(sensor) == 10 and sensor.frame_period_s == 0.25
    with pytest.raises(ValueError):
        SimSensor(two_material_sphere(), fps=0.0)
    with pytest.raises(ValueError, match="fingers"):
        SimSensor(two_material_sphere(), fingers=["pinky"])


def test_realtime_makes_the_digits_alone_of_the_last_overtaken_frames() -> None:
    """frames_from_clock: frame 0, then due 4 after it: frames 2 and 3 (the last two it
    overtook) come first, with every DIGIT reading but no camera reading."""
    sensor = SimSensor(two_material_sphere(), class_names=CLASSES, duration_s=0.6, fps=10.0, seed=0)
    due = iter([0, 4, 9])
    with sensor:
        got = list(sensor.frames_from_clock(lambda: next(due), touch_frames=2))
    assert [(f.index, f.touches_only) for f in got] == [
        (0, False),
        (2, True),
        (3, True),
        (4, False),
    ]
    for frame in got:
        assert (frame.camera is None) == frame.touches_only
        assert set(frame.tactile) == set(FINGERS)
        assert frame.time_s == pytest.approx(frame.index / 10.0)
