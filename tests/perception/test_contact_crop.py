"""Contact crop: the classifier's input window follows the contact, at native resolution."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.perception.classifier.transforms import contact_crop, preprocess


def frame_with_blob(cy: int, cx: int) -> tuple[np.ndarray, np.ndarray]:
    background = np.full((320, 240, 3), 120, dtype=np.uint8)
    image = background.copy()
    yy, xx = np.mgrid[:320, :240]
    image[(yy - cy) ** 2 + (xx - cx) ** 2 < 20**2] = 200
    return image, background


def test_crop_is_centred_on_the_contact() -> None:
    image, background = frame_with_blob(70, 180)
    crop = contact_crop(image, background, 96)
    assert crop.shape == (96, 96, 3)
    ys, xs = np.nonzero(crop[..., 0] == 200)
    assert abs(ys.mean() - 47.5) < 1.5 and abs(xs.mean() - 47.5) < 1.5


def test_crop_stays_inside_the_frame_and_falls_back_to_the_centre() -> None:
    image, background = frame_with_blob(5, 5)
    crop = contact_crop(image, background, 96)
    assert crop.shape == (96, 96, 3) and (crop[..., 0] == 200).any()
    centre = contact_crop(image, None, 96)
    np.testing.assert_array_equal(centre, image[112:208, 72:168])
    # No contact against the background: the centre as well.
    np.testing.assert_array_equal(
        contact_crop(background, background, 96), background[112:208, 72:168]
    )


def test_preprocess_without_crop_is_the_whole_frame_resize() -> None:
    image, background = frame_with_blob(160, 120)
    whole = preprocess(image, 64)
    cropped = preprocess(image, 64, crop_px=96, background=background)
    assert whole.shape == cropped.shape == (64, 64, 3)
    # The crop magnifies the blob: it covers far more of the input than in the whole frame.
    assert (cropped[..., 0] > 160).mean() > 3 * (whole[..., 0] > 160).mean()
