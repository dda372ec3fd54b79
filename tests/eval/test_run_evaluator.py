"""A fake mapping run through RunEvaluator: curve, snapshots, final metrics and pictures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.eval.run_evaluator import RunEvaluator
from tests.eval.objects import predict_by_y, two_material_sphere
from tests.viz.images import assert_png


def improving(frame: int, frames: int):
    """Wrong on a longitude wedge that shrinks to nothing by the last frame."""

    def predict(points: np.ndarray) -> np.ndarray:
        angle = np.arctan2(points[:, 1], points[:, 0]) % (2 * np.pi)
        wrong = angle < 2 * np.pi * (1 - frame / (frames - 1)) * 0.5
        return np.where(wrong, 3, predict_by_y(points))

    return predict


@pytest.mark.parametrize("expected_frames", [21, None])
def test_fake_run(tmp_path: Path, expected_frames: int | None) -> None:
    obj = two_material_sphere()
    frames = 21
    ev = RunEvaluator(
        obj,
        every_k_frames=5,
        num_surface_samples=4000,
        image_views=2,
        image_size=64,
        shape_samples=3000,
        progression_snapshots=4,
        expected_frames=expected_frames,
    )
    base = ev.baseline(lambda x: np.zeros(len(x), dtype=np.int64))
    assert base["matching_pct"] == pytest.approx(50.0, abs=3.0)
    assert "fscore_5mm" not in base  # no mesh given
    for i in range(frames):
        ev.touch("index", 0, 0 if i % 2 else 2)  # right on even... wrong on odd frames
        if ev.is_due(i, last=i == frames - 1):
            ev.step(i, 0.1 * i, improving(i, frames))
    assert [row[0] for row in ev.curve] == [0, 5, 10, 15, 20]
    pcts = [row[2] for row in ev.curve]
    assert pcts[0] == pytest.approx(50.0, abs=3.0) and pcts[-1] == 100.0
    assert all(b >= a - 1.0 for a, b in zip(pcts, pcts[1:]))
    # Unknown length: doubling frame indices; known: the first step at or after linspace(0, 20, 4)[:-1].
    expected_snapshots = [0, 5, 10, 20] if expected_frames is None else [0, 10, 15]
    assert [t for t, _ in ev.snapshots] == pytest.approx([0.1 * f for f in expected_snapshots])
    assert ev.snapshots[0][1]["pred"].shape == (1, 64, 64)

    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.051)
    final = ev.final(improving(frames - 1, frames), mesh)
    assert final["matching_pct"] == 100.0 and final["matching_pct_image"] == 100.0
    assert final["matching_curve"][-1] == [20, pytest.approx(2.0), 100.0]
    # 3000 samples are ~3 mm apart: a few nearest samples lie beyond 5 mm.
    assert final["fscore_5mm"] == pytest.approx(1.0, abs=0.01) and 0.5 < final["chamfer_mm"] < 2.5
    assert final["classifier_accuracy"]["overall"] == pytest.approx(10 / 21)
    json.dumps({"final": final, "baseline": base})  # metrics.json-ready

    paths = ev.write_pictures(
        tmp_path, improving(frames - 1, frames), mesh, base["matching_pct"], final
    )
    assert {p.name for p in paths} == {
        "material_maps.png",
        "progression.png",
        "matching_curve.png",
        "fscore_curve.png",
        "material_mesh.ply",
    }
    for path in paths:
        if path.suffix == ".png":
            assert_png(path)
    assert len(trimesh.load(tmp_path / "material_mesh.ply").vertices) == len(mesh.vertices)


def test_bad_settings_are_value_errors() -> None:
    obj = two_material_sphere()
    with pytest.raises(ValueError):
        RunEvaluator(obj, every_k_frames=0)
    with pytest.raises(ValueError):
        RunEvaluator(obj, image_views=2, progression_view=2)
