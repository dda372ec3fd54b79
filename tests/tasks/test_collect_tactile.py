"""task=collect_tactile writes a balanced ImageFolder tactile set with a manifest."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.touch_sources import (
    FeatureEdges,
    primitive_objects,
    sample_feature_touch,
    sample_touch,
)
from neuralfeels_sem.tasks.collect_tactile import run
from tests.helpers import compose_config, run_cli

CLASSES = list(DEFAULT_MATERIALS)


def _cfg(root: Path, *extra: str):
    return compose_config(
        [
            "task=collect_tactile",
            f"task.root={root}",
            "task.samples_per_class_per_sensor=2",
            "task.library_objects=[]",
            "task.sensors=[index,thumb]",
            *extra,
        ]
    )


def test_writes_a_balanced_dataset_with_manifest(tmp_path: Path) -> None:
    root = tmp_path / "tactile"
    result = run(_cfg(root))
    assert result["total"] == 2 * 4 * 2
    for sensor in ("index", "thumb"):
        for material in CLASSES:
            files = sorted((root / sensor / material).glob("*.png"))
            assert [f.name for f in files] == ["00000.png", "00001.png"]
            image = cv2.imread(str(files[0]))
            assert image.shape == (320, 240, 3)
        background = cv2.imread(str(root / "_backgrounds" / f"{sensor}.png"))
        assert background.shape == (320, 240, 3)
    # The two sensors are different DIGITs: different backgrounds.
    a = cv2.imread(str(root / "_backgrounds" / "index.png")).astype(int)
    b = cv2.imread(str(root / "_backgrounds" / "thumb.png")).astype(int)
    assert np.abs(a - b).mean() > 1.0
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["counts"] == {s: dict.fromkeys(CLASSES, 2) for s in ("index", "thumb")}
    assert manifest["classes"] == CLASSES and manifest["seed"] == 0
    assert manifest["renderer_seeds"] == {"index": 0, "thumb": 3}
    assert sum(manifest["objects"]["index"]["fabric"].values()) == 2
    # Every image has the surface curvature where it was pressed (primitives: 0 to 1/18 mm,
    # more at a box edge).
    assert sorted(manifest["curvatures"]) == sorted(manifest["presses"])
    assert all(k is None or k >= 0 for k in manifest["curvatures"].values())
    # Images show contact: they differ from the sensor's background.
    image = cv2.imread(str(root / "thumb" / "wood" / "00000.png")).astype(int)
    assert np.abs(image - b).max() > 40


def test_edge_presses_give_imprints_cut_off_by_the_sensor_border(tmp_path: Path) -> None:
    from neuralfeels_sem.perception.contact import ContactGate, edge_share

    root = tmp_path / "edge"
    run(_cfg(root, "task.edge_press_fraction=1.0", "task.sensors=[middle]"))
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["edge_presses"] == manifest["total"] == 8
    assert manifest["edge_tilt_deg"] == [15.0, 40.0]
    background = cv2.imread(str(root / "_backgrounds" / "middle.png"))
    gate, shares = ContactGate(), []
    for path in sorted(root.glob("middle/*/*.png")):
        mask = gate.mask(cv2.imread(str(path)), background)
        assert gate.in_contact(cv2.imread(str(path)), background)
        shares.append(edge_share(mask, 16))
    # Centred presses put 14 % of the contact in the border band (median, sim_v3);
    # edge presses most of it.
    assert np.median(shares) > 0.3


def test_feature_presses_are_recorded_per_image_and_press_rims(tmp_path: Path) -> None:
    root = tmp_path / "feature"
    run(_cfg(root, "task.feature_press_fraction=1.0", "task.sensors=[index]"))
    manifest = json.loads((root / "manifest.json").read_text())
    presses = manifest["presses"]
    # Every image is listed; spheres and capsules have no rim, so those fall back to centre.
    assert sorted(presses) == sorted(
        p.relative_to(root).as_posix() for p in root.glob("index/*/*.png")
    )
    assert set(presses.values()) <= {"feature", "centre"}
    assert manifest["press_counts"]["feature"] >= 1
    assert sum(manifest["press_counts"].values()) == manifest["total"] == 8
    assert manifest["feature_press_fraction"] == 1.0
    both = tmp_path / "both"
    run(_cfg(both, "task.feature_press_fraction=1.0", "task.edge_press_fraction=1.0"))
    kinds = json.loads((both / "manifest.json").read_text())["press_counts"]
    assert "feature+edge" in kinds and set(kinds) <= {"feature+edge", "edge"}
    # The default is off: a run without the key equals one with 0.0, all centred presses.
    plain, again = tmp_path / "plain", tmp_path / "again"
    run(_cfg(plain, "task.sensors=[index]"))
    run(_cfg(again, "task.sensors=[index]", "task.feature_press_fraction=0.0"))
    for path in plain.glob("index/*/*.png"):
        assert np.array_equal(
            cv2.imread(str(path)), cv2.imread(str(again / path.relative_to(plain)))
        )
    assert set(json.loads((plain / "manifest.json").read_text())["presses"].values()) == {"centre"}
    # and the option changes what is pressed: a feature image differs from the plain one.
    featured = [p for p, kind in presses.items() if kind == "feature"]
    assert any(
        not np.array_equal(cv2.imread(str(root / p)), cv2.imread(str(plain / p))) for p in featured
    )


def _features(mesh: trimesh.Trimesh, labels: np.ndarray | None = None) -> FeatureEdges:
    labels = np.zeros(len(mesh.faces), int) if labels is None else labels
    return FeatureEdges.of(MaterialObject("shape", mesh, labels, ("a", "b")))


def test_feature_edges_are_the_rims_and_edges_of_a_shape() -> None:
    box = trimesh.creation.box(extents=(0.05, 0.06, 0.04))
    edges = _features(box)
    # The 12 edges of the box (not the diagonals of its faces), pressed at 45 degrees.
    assert len(edges.length) == 12 and edges.length.sum() == pytest.approx(0.6)
    assert np.allclose(np.sort(np.abs(edges.normal), axis=1)[:, 1:], np.sqrt(0.5))
    rng = np.random.default_rng(0)
    for _ in range(10):
        touch = sample_feature_touch(edges, 0, rng)
        # On an edge: two coordinates at the box's half extents.
        at_face = np.isclose(np.abs(touch.point), [0.025, 0.03, 0.02], atol=1e-9)
        assert at_face.sum() >= 2
    assert sample_feature_touch(edges, 1, rng) is None  # no edge of material 1
    # A smooth sphere has none; a 4 mm rounded rim counts although no single edge is sharp.
    assert len(_features(trimesh.creation.icosphere(subdivisions=4, radius=0.025)).length) == 0
    rod = trimesh.creation.capsule(height=0.03, radius=0.004, count=[32, 32])
    assert len(_features(rod).length) > 0
    # An edge between two materials is never a feature of either.
    labels = (box.face_normals[:, 0] > 0.5).astype(int)  # the +x side is of material 1
    split = _features(box, labels)
    assert len(split.length) == 8 and set(split.label.tolist()) == {0}


def test_refuses_a_non_empty_root_and_unknown_objects(tmp_path: Path) -> None:
    root = tmp_path / "tactile"
    root.mkdir()
    (root / "old.txt").write_text("x")
    with pytest.raises(DataError, match="overwrite"):
        run(_cfg(root))
    with pytest.raises(ConfigError, match="nope"):
        run(_cfg(tmp_path / "other", "task.library_objects=[nope]"))
    assert not (tmp_path / "other").exists()  # nothing written before the config is checked


def test_touch_samples_lie_on_the_labelled_faces() -> None:
    objects = primitive_objects(CLASSES)
    assert len(objects) == 6 * len(CLASSES)
    rng = np.random.default_rng(0)
    for obj in objects[:6]:
        for _ in range(5):
            touch = sample_touch(obj, 0, rng)
            _, distance, _ = trimesh.proximity.closest_point(obj.mesh, touch.point[None])
            assert distance[0] < 1e-5  # trimesh closest_point is approximate on sliver faces
            assert touch.normal @ (touch.point - obj.mesh.centroid) > 0  # outward on a convex shape
            assert np.linalg.norm(touch.normal) == pytest.approx(1.0)
    with pytest.raises(ValueError):
        sample_touch(objects[0], 3, rng)  # a plastic primitive has no wood faces


@pytest.mark.slow  # a fresh interpreter (torch, hydra, GL imports): tens of seconds on 2 cores
def test_cli_bad_object_exits_2_with_one_line(tmp_path: Path) -> None:
    result = run_cli(
        [
            "task=collect_tactile",
            f"task.root={tmp_path / 'x'}",
            "task.library_objects=[nope]",
            f"hydra.run.dir={tmp_path / 'run'}",
        ]
    )
    assert result.returncode == 2, result.stderr[-2000:]
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "nope" in errors[0]
    assert "Traceback" not in result.stderr


def test_real_recording_refuses_the_simulated_sets_default_folder() -> None:
    cfg = compose_config(["task=collect_tactile", "sensor=real", "task.material=metal"])
    with pytest.raises(ConfigError, match="dataset.root=data/tactile/real"):
        run(cfg)
