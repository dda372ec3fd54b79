"""The rig's own touches written as a labelled ImageFolder set for task=eval_classifier."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.bench.rig_touches import WriteRule, collect
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.perception.classifier.dataset import load_backgrounds, scan_dataset


def test_rig_touches_are_written_with_their_ground_truth_material(tmp_path: Path) -> None:
    records = collect(tmp_path, ["patched_toy"], seed=0, frames=8)
    assert records, "the rig touches patched_toy within 0.8 s"
    written = [r for r in records if r["written"]]
    files = sorted(tmp_path.glob("*/*/*.png"))
    files = [f for f in files if f.parent.parent.name != "_backgrounds"]
    assert len(files) == len(written) > 0
    for record in written:
        path = tmp_path / record["finger"] / record["material"]
        path = path / f"patched_toy_0_{record['frame']:04d}.png"
        assert cv2.imread(str(path)).shape == (320, 240, 3)
        assert record["purity"] >= 0.95 and record["contact_px"] > 0
        assert 0.0 <= record["edge_share"] <= 1.0
    assert {r["material"] for r in records} <= {"plastic", "fabric"}  # patched_toy's materials
    assert json.loads((tmp_path / "touches.json").read_text()) == records
    # task=eval_classifier reads it: ImageFolder layout with each DIGIT's background.
    samples = scan_dataset(tmp_path, list(DEFAULT_MATERIALS), False)
    assert len(samples) == len(written)
    assert sorted(load_backgrounds(tmp_path)) == ["index", "middle", "ring", "thumb"]
    # Same seed, same frames: the run is repeatable.
    again = collect(tmp_path / "again", ["patched_toy"], seed=0, frames=8)
    assert again == records
    a = cv2.imread(str(files[0]))
    b = cv2.imread(str(tmp_path / "again" / files[0].relative_to(tmp_path)))
    assert np.array_equal(a, b)
    # Thinned for training: edge imprints on every 2nd frame, other touches on every 3rd.
    thin = collect(
        tmp_path / "thin", ["patched_toy"], seed=0, frames=8, rule=WriteRule(keep_every=(2, 3))
    )
    for full, kept in zip(records, thin, strict=True):
        stride = 2 if full["edge_share"] > 0.5 else 3
        assert kept == {**full, "written": full["written"] and full["frame"] % stride == 0}
    assert len(list((tmp_path / "thin").glob("[imrt]*/*/*.png"))) == sum(r["written"] for r in thin)
    with pytest.raises(ValueError, match="keep-every"):
        WriteRule(keep_every=(0, 1))


def test_unknown_object_is_a_one_line_error(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="neither a shipped object"):
        collect(tmp_path, ["teapot"], frames=1)
    # the evaluation set is never data: refused before anything is written
    with pytest.raises(ValueError, match="evaluation set"):
        collect(tmp_path, ["random_2", "random_1003"], frames=1)
    assert not any(tmp_path.iterdir())


def test_generated_development_objects_are_touched_as_in_a_map_run(tmp_path: Path) -> None:
    from neuralfeels_sem.objects.random_object import make_random_object

    records = collect(tmp_path, ["random_3"], seed=0, frames=12)
    obj = make_random_object(3, DEFAULT_MATERIALS)
    assert records and {r["object"] for r in records} == {"random_3"}
    assert {r["material"] for r in records} <= set(obj.generation["materials"])
    assert len(list(tmp_path.glob("*/*/random_3_0_*.png"))) == sum(r["written"] for r in records)


def test_patch_crops_are_labelled_with_the_material_under_their_centre() -> None:
    from types import SimpleNamespace

    from neuralfeels_sem.bench.rig_touches import (
        CROP_PX,
        MAX_PATCHES,
        PATCH_SPACING_PX,
        _patch_crops,
    )
    from neuralfeels_sem.perception.classifier.patches import patch_centres

    # A wide imprint across a border: fabric (1) left of column 150, metal (2) right of it.
    material = np.full((320, 240), -1, dtype=np.int64)
    material[:, :150], material[:, 150:] = 1, 2
    contact = np.zeros((320, 240), dtype=bool)
    contact[100:220, 20:230] = True
    image = np.random.default_rng(0).integers(0, 255, (320, 240, 3), dtype=np.uint8)
    out = SimpleNamespace(contact_mask=contact, material=material, image=image)
    crops = _patch_crops(out, contact, WriteRule())
    assert {label for label, _ in crops} == {1, 2}
    assert all(crop.shape == (CROP_PX, CROP_PX, 3) for _, crop in crops)
    # A crop's label is the material at its centre: find each crop in the frame.
    for label, crop in crops:
        hits = np.argwhere((image[:, :, 0] == crop[0, 0, 0]) & (image[:, :, 1] == crop[0, 0, 1]))
        (r0, c0) = next(
            (r, c) for r, c in hits if np.array_equal(image[r : r + CROP_PX, c : c + CROP_PX], crop)
        )
        assert material[r0 + CROP_PX // 2, c0 + CROP_PX // 2] == label
    # A centre whose disc (half the patch spacing) straddles the border is skipped.
    centres = patch_centres(contact, PATCH_SPACING_PX, MAX_PATCHES)
    straddling = np.abs(centres[:, 1] - 150) < PATCH_SPACING_PX / 2 - 8  # >= 8 % across
    assert straddling.any() and len(crops) <= len(centres) - straddling.sum()
    with pytest.raises(ValueError, match="mixed-patches"):
        WriteRule(patch_every=-1)
    with pytest.raises(ValueError, match="min-purity"):
        WriteRule(min_purity=0.3)


def test_mixed_imprints_are_written_as_patch_crops_only_when_asked(tmp_path: Path) -> None:
    from neuralfeels_sem.bench.rig_touches import CROP_PX

    plain = collect(tmp_path / "plain", ["random_20"], seed=3, frames=30)
    assert not list((tmp_path / "plain").glob("*/*/*_p*.png"))
    assert all(r["patches"] == 0 for r in plain)
    rule = WriteRule(patch_every=1)
    records = collect(tmp_path / "mixed", ["random_20"], seed=3, frames=30, rule=rule)
    assert [{**r, "patches": 0} for r in records] == plain  # pure touches as before
    with_patches = [r for r in records if r["patches"]]
    assert with_patches, "random_20's imprints straddle its materials within 3 s"
    for r in with_patches:
        assert r["purity"] < 0.95 and r["edge_share"] <= 0.5 and not r["written"]
    crops = sorted((tmp_path / "mixed").glob("*/*/*_p*.png"))
    assert len(crops) == sum(r["patches"] for r in records)
    assert {cv2.imread(str(c)).shape for c in crops} == {(CROP_PX, CROP_PX, 3)}


def test_patch_crop_side_is_the_shipped_classifiers() -> None:
    from neuralfeels_sem.bench.rig_touches import CROP_PX
    from neuralfeels_sem.perception.classifier import SHIPPED_CHECKPOINT
    from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint

    assert load_checkpoint(SHIPPED_CHECKPOINT).meta["crop_px"] == CROP_PX
