"""The rig's own touches written as a labelled ImageFolder set for task=eval_classifier."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from neuralfeels_sem.bench.rig_touches import collect
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
    thin = collect(tmp_path / "thin", ["patched_toy"], seed=0, frames=8, keep_every=(2, 3))
    for full, kept in zip(records, thin, strict=True):
        stride = 2 if full["edge_share"] > 0.5 else 3
        assert kept == {**full, "written": full["written"] and full["frame"] % stride == 0}
    assert len(list((tmp_path / "thin").glob("[imrt]*/*/*.png"))) == sum(r["written"] for r in thin)
    with pytest.raises(ValueError, match="keep-every"):
        collect(tmp_path / "bad", ["patched_toy"], frames=1, keep_every=(0, 1))


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
