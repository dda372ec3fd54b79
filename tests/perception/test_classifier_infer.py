"""MaterialClassifier: lazy loading, class-list check, contact gate, confidence, and the oracle."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.core.digit import DIGIT_INTRINSICS
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.classifier import MaterialClassifier, OracleClassifier
from neuralfeels_sem.perception.contact import edge_share
from neuralfeels_sem.perception.touch import NO_LABEL
from tests.perception.synthetic_tactile import CLASSES, background, pressed


def reading(finger: str, image: np.ndarray, bg: np.ndarray | None, **gt) -> TactileReading:
    return TactileReading(
        finger=finger,
        image=image,
        world_T_sensor=np.eye(4),
        intrinsics=DIGIT_INTRINSICS,
        background=bg,
        **gt,
    )


def test_constructor_does_no_io_and_class_mismatch_is_a_config_error(
    untrained_checkpoint: Path,
) -> None:
    clf = MaterialClassifier(
        CLASSES, checkpoint="/nonexistent/classifier.pt"
    )  # no error until used
    assert clf._model is None
    clf = MaterialClassifier(
        ["plastic", "metal", "fabric"], checkpoint=str(untrained_checkpoint), device="cpu"
    )
    with pytest.raises(ConfigError, match="trained for .* but materials="):
        clf.open()


def test_classify_gates_contact_and_returns_probabilities(untrained_checkpoint: Path) -> None:
    rng = np.random.default_rng(0)
    clf = MaterialClassifier(
        CLASSES, checkpoint=str(untrained_checkpoint), device="cpu", min_confidence=0.0
    )
    fingers = ["index", "middle", "ring", "thumb"]
    images = [background(0), pressed(1, 0, rng), pressed(2, 3, rng), background(3)]
    readings = [reading(f, im, background(i)) for i, (f, im) in enumerate(zip(fingers, images))]
    labels = clf.classify(readings)
    assert [t.finger for t in labels] == fingers
    assert [t.contact for t in labels] == [False, True, True, False]
    for t in (labels[0], labels[3]):
        assert t.label == NO_LABEL and t.probs is None and not t.usable
    probs = clf.predict_images(np.stack([images[1], images[2]]))
    for t, p in zip((labels[1], labels[2]), probs):
        np.testing.assert_allclose(t.probs, p, rtol=1e-5, atol=1e-6)
        assert t.probs.sum() == pytest.approx(1.0, abs=1e-5)
        assert t.label == int(p.argmax()) and t.confidence == pytest.approx(float(p.max()))
        assert t.usable


def test_low_confidence_is_marked_not_forced(untrained_checkpoint: Path) -> None:
    clf = MaterialClassifier(
        CLASSES, checkpoint=str(untrained_checkpoint), device="cpu", min_confidence=0.99
    )
    t = clf.classify([reading("index", pressed(0, 1, np.random.default_rng(1)), background(0))])[0]
    assert (
        t.contact and t.probs is not None and t.confidence < 0.99
    )  # an untrained net is never that sure
    assert t.low_confidence and t.label == NO_LABEL and not t.usable


def test_backgrounds_from_folder_or_first_frame(untrained_checkpoint: Path, tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "index.png"), background(0)[..., ::-1])
    press = pressed(0, 2, np.random.default_rng(2))
    clf = MaterialClassifier(
        CLASSES, checkpoint=str(untrained_checkpoint), device="cpu", background_dir=str(tmp_path)
    )
    assert clf.classify([reading("index", press, None)])[0].contact
    # No background anywhere: the first frame of a finger becomes its reference.
    clf = MaterialClassifier(CLASSES, checkpoint=str(untrained_checkpoint), device="cpu")
    assert not clf.classify([reading("ring", background(2), None)])[0].contact
    assert clf.classify([reading("ring", pressed(2, 0, np.random.default_rng(3)), None)])[0].contact
    strict = MaterialClassifier(
        CLASSES, checkpoint=str(untrained_checkpoint), device="cpu", first_frame_background=False
    )
    with pytest.raises(ConfigError, match="no background frame for finger thumb"):
        strict.classify([reading("thumb", background(3), None)])


def test_predict_images_checks_shape(untrained_checkpoint: Path) -> None:
    clf = MaterialClassifier(CLASSES, checkpoint=str(untrained_checkpoint), device="cpu")
    assert clf.predict_images(np.zeros((0, 320, 240, 3), np.uint8)).shape == (0, 4)
    assert clf.predict_images(np.zeros((3, 320, 240, 3), np.uint8)).shape == (3, 4)
    with pytest.raises(ValueError):
        clf.predict_images(np.zeros((320, 240, 3), np.uint8))


def test_oracle_takes_majority_ground_truth_under_contact() -> None:
    oracle = OracleClassifier(CLASSES, min_confidence=0.5)
    image = background(0)
    mask = np.zeros((320, 240), bool)
    mask[100:200, 50:150] = True  # 10000 px
    material = np.full((320, 240), -1, np.int16)
    material[100:200, 50:120] = 2  # 7000 px fabric
    material[100:200, 120:150] = 1  # 3000 px metal
    material[0:50] = 3  # outside the contact: ignored
    touch, none, ignore = oracle.classify(
        [
            reading("index", image, None, gt_contact_mask=mask, gt_material=material),
            reading(
                "middle", image, None, gt_contact_mask=np.zeros_like(mask), gt_material=material
            ),
            reading(
                "ring", image, None, gt_contact_mask=mask, gt_material=np.full_like(material, -1)
            ),
        ]
    )
    assert touch.contact and touch.label == 2 and touch.confidence == pytest.approx(0.7)
    np.testing.assert_allclose(touch.probs, [0.0, 0.3, 0.7, 0.0])
    assert not none.contact and none.label == NO_LABEL
    assert ignore.contact and ignore.label == NO_LABEL and not ignore.usable
    strict = OracleClassifier(CLASSES, min_confidence=0.8)
    low = strict.classify(
        [reading("index", image, None, gt_contact_mask=mask, gt_material=material)]
    )[0]
    assert low.low_confidence and low.label == NO_LABEL


def test_oracle_needs_ground_truth() -> None:
    with pytest.raises(ConfigError, match="needs simulator ground truth"):
        OracleClassifier(CLASSES).classify([reading("thumb", background(0), None)])


def test_imprint_cut_off_by_the_sensor_edge_gets_no_label(untrained_checkpoint: Path) -> None:
    """A strip along the border (a tilted pad's edge contact) is abstained, not guessed."""
    bg = background(0)
    strip = bg.astype(np.int16)
    strip[100:220, 222:] += 60  # contact only in the outer 18 columns
    strip = np.clip(strip, 0, 255).astype(np.uint8)
    centred = pressed(0, 1, np.random.default_rng(2))
    kwargs = dict(checkpoint=str(untrained_checkpoint), device="cpu", min_confidence=0.0)
    edge, centre = MaterialClassifier(CLASSES, **kwargs).classify(
        [reading("index", strip, bg), reading("index", centred, bg)]
    )
    assert edge.contact and edge.probs is not None
    assert edge.low_confidence and edge.label == NO_LABEL and not edge.usable
    assert edge.at_edge and not centre.at_edge  # press fusion tells the two abstentions apart
    assert centre.usable
    off = MaterialClassifier(CLASSES, max_edge_share=1.0, **kwargs)
    assert off.classify([reading("index", strip, bg)])[0].usable
    with pytest.raises(ValueError, match="max_edge_share"):
        MaterialClassifier(CLASSES, max_edge_share=0.0)
    # With edge_label_weight the strip keeps its label, trusted less; a centred touch not.
    weak, full = MaterialClassifier(CLASSES, edge_label_weight=0.3, **kwargs).classify(
        [reading("index", strip, bg), reading("index", centred, bg)]
    )
    assert weak.usable and weak.weight == 0.3 and weak.label == int(edge.probs.argmax())
    assert full.usable and full.weight == 1.0
    with pytest.raises(ValueError, match="edge_label_weight"):
        MaterialClassifier(CLASSES, edge_label_weight=1.5)
    with pytest.raises(ValueError, match="edge_label_weight"):
        EfficientNetClassifierConfig(edge_label_weight=-0.1)


def test_edge_share_counts_border_pixels() -> None:
    mask = np.zeros((320, 240), bool)
    assert edge_share(mask, 16) == 0.0
    mask[150:170, 0:20] = True  # 20 columns, 16 of them in the border band
    assert edge_share(mask, 16) == pytest.approx(0.8)
    mask[:] = False
    mask[100:200, 100:140] = True
    assert edge_share(mask, 16) == 0.0


def test_the_traced_cpu_model_is_cached_on_disk_by_checkpoint_content(
    untrained_checkpoint: Path, tmp_path: Path, caplog
) -> None:
    """Traced once and saved; the next open loads it (the same outputs to the bit); a copy
    of the checkpoint elsewhere shares the file; a damaged file is traced over."""
    import shutil

    import torch

    from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
    from neuralfeels_sem.perception.classifier.model import fold_batch_norms, fold_same_padding
    from neuralfeels_sem.perception.classifier.traced_cache import cached_trace

    ckpt = load_checkpoint(untrained_checkpoint)
    eager = fold_same_padding(fold_batch_norms(ckpt.build(torch.device("cpu"))))
    built = []

    def folded():
        built.append(1)
        return eager

    cache = tmp_path / "cache"
    cache.mkdir()
    first = cached_trace(untrained_checkpoint, 32, folded, cache)
    (saved,) = cache.glob("*.pt")
    copy = tmp_path / "elsewhere.pt"
    shutil.copy(untrained_checkpoint, copy)
    loaded = cached_trace(copy, 32, folded, cache)
    assert len(built) == 1 and loaded is not first  # loaded from the file, not traced
    x = torch.rand(3, 3, 32, 32).contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        assert torch.equal(loaded(x), eager(x)) and torch.equal(first(x), eager(x))
    saved.write_bytes(b"not a model")
    again = cached_trace(untrained_checkpoint, 32, folded, cache)
    assert len(built) == 2 and "tracing again" in caplog.text
    with torch.inference_mode():
        assert torch.equal(again(x), eager(x))
    assert cached_trace(untrained_checkpoint, 32, folded, cache) is not None
    assert len(built) == 2  # the damaged file was replaced
