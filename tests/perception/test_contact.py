"""Contact gate: background difference on synthetic frames and on real DIGIT frames."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.perception.contact import ContactGate, shows_change
from tests.perception.synthetic_tactile import background, pressed


def _read(path: Path) -> np.ndarray:
    return np.ascontiguousarray(cv2.imread(str(path), cv2.IMREAD_COLOR)[..., ::-1])


def recaptured(image: np.ndarray, seed: int) -> np.ndarray:
    """The same no-contact view captured again: pixel noise, exposure drift, JPEG."""
    rng = np.random.default_rng(seed)
    noisy = image.astype(np.float32) * rng.uniform(0.95, 1.05) + rng.uniform(-6, 6, 3)
    noisy += rng.normal(0, 3.0, image.shape)
    ok, buf = cv2.imencode(
        ".jpg", np.clip(noisy, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 85]
    )
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


def test_synthetic_background_noise_and_drift_are_not_contact() -> None:
    gate = ContactGate()
    bg = background(0)
    for seed in range(5):
        assert not gate.in_contact(recaptured(bg, seed), bg)


def test_synthetic_press_is_contact_where_it_presses() -> None:
    gate = ContactGate()
    bg = background(1)
    image = pressed(1, 2, np.random.default_rng(0))
    assert gate.in_contact(image, bg)
    mask = gate.mask(image, bg)
    assert mask[140:180, 100:140].mean() > 0.5  # the patch centre
    assert mask[:20].mean() == 0.0 and mask[-20:].mean() < 0.2  # far from it


def test_small_blob_below_min_area_is_not_contact() -> None:
    gate = ContactGate(min_area=0.01)
    bg = background(2)
    image = bg.copy()
    cv2.circle(image, (120, 160), 8, (255, 255, 255), -1)  # ~0.3 % of the image, below 1 %
    assert 0 < gate.contact_fraction(image, bg) < 0.01
    assert not gate.in_contact(image, bg)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        ContactGate(threshold=0)
    with pytest.raises(ValueError):
        ContactGate(min_area=1.5)
    with pytest.raises(ValueError, match="differ in shape"):
        ContactGate().mask(np.zeros((320, 240, 3), np.uint8), np.zeros((240, 320, 3), np.uint8))


def test_real_backgrounds_are_not_contact(shared_data: Path) -> None:
    """Each real background is its sensor's reference; a re-capture of it is no contact.

    The 35 frames come from different DIGITs (their LED glows differ far more than any
    contact), so as a real user would, each sensor is compared with its own background.
    """
    files = sorted((shared_data / "digit_real" / "backgrounds").iterdir())
    assert len(files) == 35
    gate = ContactGate()
    flagged = [
        f.name for i, f in enumerate(files) if gate.in_contact(recaptured(_read(f), i), _read(f))
    ]
    assert flagged == []


def test_real_background_pairs_of_one_sensor_are_not_contact(shared_data: Path) -> None:
    """Frames that are two captures of one sensor (nearly identical views) differ by no contact."""
    folder = shared_data / "digit_real" / "backgrounds"
    gate = ContactGate()
    for a, b in [
        ("bg.jpg", "bg_1.jpg"),
        ("bg.jpg", "bg_2.jpg"),
        ("bg_4.jpg", "bg_29.jpg"),
        ("bg_6.jpg", "bg_26.jpg"),
    ]:
        assert not gate.in_contact(_read(folder / a), _read(folder / b)), (a, b)


def test_real_contact_frames_are_contact(shared_data: Path) -> None:
    """The two grasp frames against the background of their lab's sensor (aurova_bg_1)."""
    reference = _read(shared_data / "digit_real" / "backgrounds" / "aurova_bg_1.png")
    gate = ContactGate()
    for name in ("ycb_grasp_1.png", "ycb_grasp_2.png"):
        image = _read(shared_data / "digit_real" / "contact" / name)
        assert gate.in_contact(image, reference), name
        assert gate.contact_fraction(image, reference) > 0.1


def test_change_score_is_the_blurred_summed_rgb_change_less_the_drift() -> None:
    rng = np.random.default_rng(3)
    quiet = rng.integers(0, 256, (64, 48, 3), dtype=np.uint8)
    frame = np.clip(quiet + rng.integers(-40, 60, (64, 48, 3)), 0, 255).astype(np.uint8)
    gate = ContactGate(blur_px=2.0)
    diff = frame.astype(np.float32) - quiet.astype(np.float32)
    diff -= np.median(diff[::4, ::4].reshape(-1, 3), axis=0)
    expected = cv2.GaussianBlur(np.abs(diff).sum(axis=2), (0, 0), 2.0)
    np.testing.assert_array_equal(gate.difference(frame, quiet), expected)


def test_shows_change_ignores_pixel_noise_and_sees_a_press() -> None:
    bg = background(4)
    rng = np.random.default_rng(4)
    for _ in range(5):  # the simulator's pixel noise (std 2 grey levels per channel)
        noisy = np.clip(bg + rng.normal(0.0, 2.0, bg.shape), 0, 255).astype(np.uint8)
        assert not shows_change(noisy, bg)
    assert shows_change(pressed(4, 2, rng), bg)
    small = bg.copy()  # a press smaller than any the depth network reports (150 px)
    cv2.circle(small, (120, 160), 5, (255, 255, 255), -1)
    assert shows_change(small, bg)
    with pytest.raises(ValueError, match="differ in shape"):
        shows_change(bg, bg[:, :200])


def test_real_contact_frames_show_change(shared_data: Path) -> None:
    reference = _read(shared_data / "digit_real" / "backgrounds" / "aurova_bg_1.png")
    for name in ("ycb_grasp_1.png", "ycb_grasp_2.png"):
        assert shows_change(_read(shared_data / "digit_real" / "contact" / name), reference)
