"""Patch readings: centres across an imprint, each pixel labelled by its nearest patch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_INTRINSICS, DIGIT_WIDTH
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.checkpoint import save_checkpoint
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.perception.classifier.patches import (
    crop_around,
    crop_contact_share,
    patch_centres,
    pixel_labels,
)
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD
from neuralfeels_sem.perception.touch import NO_LABEL
from tests.perception.synthetic_tactile import CLASSES, background, pressed


def _disc(radius: float, centre=(160, 120)) -> np.ndarray:
    v, u = np.mgrid[0:DIGIT_HEIGHT, 0:DIGIT_WIDTH]
    return (v - centre[0]) ** 2 + (u - centre[1]) ** 2 <= radius**2


def test_centres_start_at_the_centroid_and_cover_the_contact_within_the_spacing() -> None:
    mask = _disc(100)
    centres = patch_centres(mask, spacing_px=56, max_patches=64)
    np.testing.assert_allclose(centres[0], [160, 120], atol=0.5)
    rows, cols = np.nonzero(mask)
    pixels = np.column_stack([rows, cols])
    gap = np.min(np.linalg.norm(pixels[:, None] - centres[None], axis=2), axis=1)
    # Farthest-point sampling runs on every 4th pixel: the rest are within the spacing
    # plus the sampling stride's diagonal.
    assert gap.max() <= 56 + 4 * np.sqrt(2)
    assert len(patch_centres(mask, spacing_px=56, max_patches=3)) == 3
    assert len(patch_centres(_disc(20), spacing_px=56, max_patches=8)) == 1  # one crop holds it
    assert patch_centres(np.zeros_like(mask), 56, 8).shape == (0, 2)
    with pytest.raises(ValueError, match="spacing_px"):
        patch_centres(mask, 0, 8)


def test_each_pixel_takes_its_nearest_confident_patch_within_reach() -> None:
    centres = np.array([[100.0, 60.0], [100.0, 180.0], [250.0, 120.0]])
    labels = np.array([0, 2, NO_LABEL])  # the third patch abstained
    confidence = np.array([0.9, 0.95, 0.5])
    out, conf = pixel_labels((DIGIT_HEIGHT, DIGIT_WIDTH), centres, labels, confidence, 56.0)
    assert out[100, 50] == 0 and conf[100, 50] == pytest.approx(0.9)
    assert out[100, 190] == 2 and conf[100, 190] == pytest.approx(0.95)
    assert out[250, 120] == NO_LABEL and conf[250, 120] == 0.0  # only the abstained patch near
    assert out[100, 119] == NO_LABEL  # 59 px from both labelled patches: out of reach
    wide, _ = pixel_labels((DIGIT_HEIGHT, DIGIT_WIDTH), centres, labels, confidence, 70.0)
    assert wide[100, 119] == 0 and wide[100, 121] == 2  # the border halfway between
    none, _ = pixel_labels((10, 10), centres[:1], np.array([NO_LABEL]), np.array([0.1]), 56.0)
    assert (none == NO_LABEL).all()


def test_crop_around_stays_inside_the_image() -> None:
    image = np.arange(DIGIT_HEIGHT * DIGIT_WIDTH * 3, dtype=np.uint8).reshape(
        DIGIT_HEIGHT, DIGIT_WIDTH, 3
    )
    assert crop_around(image, np.array([0.0, 0.0]), 112).shape == (112, 112, 3)
    np.testing.assert_array_equal(crop_around(image, np.array([0.0, 0.0]), 112), image[:112, :112])
    np.testing.assert_array_equal(
        crop_around(image, np.array([160.0, 120.0]), 112), image[104:216, 64:176]
    )


@pytest.fixture(scope="module")
def crop_checkpoint(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("ckpt") / "classifier.pt"
    save_checkpoint(
        path, build_model(4), CLASSES, 32, list(IMAGENET_MEAN), list(IMAGENET_STD),
        meta={"crop_px": 112},
    )  # fmt: skip
    return path


def test_crop_contact_share_is_the_imprint_share_of_the_crop_crop_around_takes() -> None:
    rng = np.random.default_rng(0)
    mask = rng.random((DIGIT_HEIGHT, DIGIT_WIDTH)) < 0.3
    share = crop_contact_share(mask, 112)
    for r, c in [(0, 0), (100, 50), (319, 239), (160, 120), (57, 3), (200, 236)]:
        expected = crop_around(mask, np.array([r, c], dtype=float), 112).mean()
        assert share[r, c] == pytest.approx(expected, abs=1e-12)
    disc = crop_contact_share(_disc(100), 112)
    assert disc[160, 120] == 1.0 and disc[60, 120] < 0.5  # the centre full, the rim half empty


def test_eligible_pixels_keep_the_centres_past_the_centroid_inside_the_imprint() -> None:
    mask = _disc(100)
    inner = crop_contact_share(mask, 112) >= 0.7
    centres = patch_centres(mask, spacing_px=56, max_patches=64, eligible=inner)
    np.testing.assert_allclose(centres[0], [160, 120], atol=0.5)
    r, c = np.round(centres[1:]).astype(int).T
    assert len(centres) > 1 and inner[r, c].all()
    everywhere = patch_centres(mask, spacing_px=56, max_patches=64)
    rr, cc = np.round(everywhere[1:]).astype(int).T
    assert not inner[rr, cc].all()  # unconstrained, the far ends lie on the rim
    # Nothing eligible past the centroid: the centroid's crop reads the whole touch.
    none = patch_centres(mask, 56, 64, eligible=np.zeros_like(mask))
    assert len(none) == 1
    with pytest.raises(ValueError, match="eligible"):
        patch_centres(mask, 56, 8, eligible=np.ones((3, 3), dtype=bool))


def test_patch_min_contact_reads_fewer_rim_crops(crop_checkpoint: Path) -> None:
    rng = np.random.default_rng(3)
    touch = TactileReading("index", pressed(1, 0, rng), np.eye(4), DIGIT_INTRINSICS, background(1))
    kwargs = {"checkpoint": str(crop_checkpoint), "device": "cpu", "patch_spacing_px": 40}
    anywhere, inside = (
        _MarkedRed(CLASSES, **kwargs),
        _MarkedRed(CLASSES, patch_min_contact=0.8, **kwargs),
    )
    anywhere.classify([touch]), inside.classify([touch])
    assert 1 <= inside.read < anywhere.read
    with pytest.raises(ValueError, match="patch_min_contact"):
        EfficientNetClassifierConfig(patch_min_contact=1.5)
    with pytest.raises(ValueError, match="patch_min_contact"):
        MaterialClassifier(CLASSES, patch_min_contact=-0.1)


def test_classify_reads_patches_of_a_touch_unless_it_is_cut_off_by_the_edge(
    crop_checkpoint: Path,
) -> None:
    rng = np.random.default_rng(0)
    kwargs = {"checkpoint": str(crop_checkpoint), "device": "cpu", "min_confidence": 0.0}
    image = pressed(1, 0, rng)
    touch = TactileReading("index", image, np.eye(4), DIGIT_INTRINSICS, background=background(1))
    plain = MaterialClassifier(CLASSES, **kwargs).classify([touch])[0]
    assert plain.contact and plain.pixel_labels is None and not plain.has_pixel_labels
    clf = MaterialClassifier(CLASSES, patch_spacing_px=40, max_patches=32, **kwargs)
    label = clf.classify([touch])[0]
    assert label.label == plain.label  # the touch's own label is the centre crop's
    assert label.has_pixel_labels and label.pixel_labels.shape == image.shape[:2]
    contact = clf.contact_mask(touch)
    assert (label.pixel_labels[contact] != NO_LABEL).all()  # min_confidence 0: all read
    capped = MaterialClassifier(CLASSES, patch_spacing_px=40, max_patches=2, **kwargs)
    assert (capped.classify([touch])[0].pixel_labels[contact] == NO_LABEL).any()  # out of reach
    centre = np.round(np.argwhere(contact).mean(axis=0)).astype(int)
    assert label.pixel_labels[tuple(centre)] == label.label
    empty = TactileReading("ring", background(2), np.eye(4), DIGIT_INTRINSICS, background(2))
    assert clf.classify([empty])[0].pixel_labels is None
    edge = MaterialClassifier(
        CLASSES, patch_spacing_px=40, max_edge_share=0.01, edge_px=100, **kwargs
    )
    gated = edge.classify([touch])[0]
    assert gated.label == NO_LABEL and gated.pixel_labels is None  # edge-gated: no label at all
    with pytest.raises(ValueError, match="patch_spacing_px"):
        MaterialClassifier(CLASSES, patch_spacing_px=-1)
    with pytest.raises(ValueError, match="patch_spacing_px"):
        EfficientNetClassifierConfig(patch_spacing_px=300)


class _MarkedRed(MaterialClassifier):
    """Reads wood (3) in crops that are mostly marked red, plastic (0) elsewhere, at 0.97;
    counts the images it is given. A whole frame is judged by its central crop."""

    read = 0

    def predict_images(self, images, backgrounds=None) -> np.ndarray:
        self.open()
        images = np.asarray(images)
        self.read += len(images)
        h, w = images.shape[1:3]
        centre = images[:, h // 2 - 56 : h // 2 + 56, w // 2 - 56 : w // 2 + 56, 0]
        wood = (centre == 255).mean(axis=(1, 2)) > 0.5
        probs = np.full((len(images), 4), 0.01, dtype=np.float32)
        probs[np.arange(len(images)), np.where(wood, 3, 0)] = 0.97
        return probs


def test_probing_the_far_ends_first_skips_the_rest_only_of_a_touch_of_one_material(
    crop_checkpoint: Path,
) -> None:
    rng = np.random.default_rng(3)
    image = pressed(1, 0, rng)
    marked = image.copy()
    marked[260:, :, 0] = 255  # the imprint's far end on another material
    kwargs = {"checkpoint": str(crop_checkpoint), "device": "cpu", "patch_spacing_px": 40}
    for frame, whole in ((image, True), (marked, False)):
        touch = TactileReading("index", frame, np.eye(4), DIGIT_INTRINSICS, background(1))
        every, probed = _MarkedRed(CLASSES, **kwargs), _MarkedRed(CLASSES, patch_probe=2, **kwargs)
        full, quick = every.classify([touch])[0], probed.classify([touch])[0]
        patches = len(patch_centres(every.contact_mask(touch), 40, 8))
        assert patches == 8 and every.read == patches
        # One material at the centre and both far ends: the other five are not read, and
        # every pixel gets what reading them would have given.
        assert probed.read == (3 if whole else patches)
        np.testing.assert_array_equal(quick.pixel_labels, full.pixel_labels)
        np.testing.assert_array_equal(quick.pixel_confidence, full.pixel_confidence)
        assert (3 in full.pixel_labels) != whole
    with pytest.raises(ValueError, match="patch_probe"):
        EfficientNetClassifierConfig(patch_probe=-1)


def wood_at_far_end() -> TactileReading:
    """A press whose far end _MarkedRed reads as wood at 0.97, its centre as plastic."""
    marked = pressed(1, 0, np.random.default_rng(3))
    marked[260:, :, 0] = 255
    return TactileReading("index", marked, np.eye(4), DIGIT_INTRINSICS, background(1))


def test_a_patch_naming_another_material_than_the_centre_needs_patch_disagree_confidence(
    crop_checkpoint: Path,
) -> None:
    touch = wood_at_far_end()
    kwargs = {"checkpoint": str(crop_checkpoint), "device": "cpu", "patch_spacing_px": 40}
    for bar, wood_kept in ((0.0, True), (0.96, True), (0.98, False)):
        label = _MarkedRed(CLASSES, patch_disagree_confidence=bar, **kwargs).classify([touch])[0]
        assert label.label == 0 and (3 in label.pixel_labels) == wood_kept
        assert (label.pixel_labels[clf_contact(touch)] == 0).any()  # the centre's side stays
    with pytest.raises(ValueError, match="patch_disagree_confidence"):
        EfficientNetClassifierConfig(patch_disagree_confidence=2.0)
    with pytest.raises(ValueError, match="patch_disagree_confidence"):
        MaterialClassifier(CLASSES, patch_disagree_confidence=-1.0)


def clf_contact(touch: TactileReading) -> np.ndarray:
    return MaterialClassifier(CLASSES).contact_mask(touch)


def test_pixel_labels_take_the_first_of_equally_near_centres_as_argmin_would() -> None:
    rng = np.random.default_rng(0)
    shape = (40, 30)
    for trial in range(50):
        k = int(rng.integers(1, 9))
        centres = np.round(rng.uniform(0, 40, (k, 2)))  # whole pixels: ties happen
        if k > 1 and trial % 2:
            centres[1] = centres[0]
        labels = rng.integers(NO_LABEL, 4, k)
        labels[0] = max(labels[0], 0)
        confidence = rng.uniform(0.5, 1.0, k).astype(np.float32)
        out, conf = pixel_labels(shape, centres, labels, confidence, 12.0)
        kept = labels != NO_LABEL
        rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
        d2 = (rows[..., None] - centres[kept, 0]) ** 2 + (cols[..., None] - centres[kept, 1]) ** 2
        nearest = d2.argmin(axis=-1)
        near = d2.min(axis=-1) <= 12.0**2
        assert (out[near] == labels[kept][nearest[near]]).all()
        assert (out[~near] == NO_LABEL).all()
        assert (conf[near] == confidence[kept][nearest[near]]).all()


def test_edge_extent_sets_where_a_trusted_edge_imprints_label_reaches(
    crop_checkpoint: Path,
) -> None:
    touch = wood_at_far_end()
    contact = clf_contact(touch)
    kwargs = {
        "checkpoint": str(crop_checkpoint),
        "device": "cpu",
        "patch_spacing_px": 40,
        "max_edge_share": 0.01,
        "edge_px": 100,
        "edge_min_confidence": 0.95,
    }  # fmt: skip  (every imprint is an edge one, trusted alone at 0.97)

    def classify(extent: str):
        label = _MarkedRed(CLASSES, edge_extent=extent, **kwargs).classify([touch])[0]
        assert label.at_edge and label.label == 0 and label.usable
        return label

    assert classify("whole").pixel_labels is None  # the label covers the whole imprint
    patches = classify("patches").pixel_labels
    assert (patches[contact] == 0).any() and 3 not in patches  # wood is not backed: abstains
    centre = classify("centre").pixel_labels
    rows = np.argwhere(contact)[:, 0]
    assert set(np.unique(centre[contact])) == {0, NO_LABEL}  # the far end lies out of reach
    assert (centre[contact][rows > rows.mean() + 56] == NO_LABEL).all()
    with pytest.raises(ValueError, match="classifier.edge_extent"):
        EfficientNetClassifierConfig(edge_extent="rim")
    with pytest.raises(ValueError, match="classifier.edge_extent"):
        MaterialClassifier(CLASSES, edge_extent="all")
