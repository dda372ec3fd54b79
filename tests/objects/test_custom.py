"""object=custom: mesh + label formats round-trip; every bad input is one clear UserError line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.errors import ConfigError, DataError, UserError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.custom import load_custom_object
from neuralfeels_sem.objects.example_files import EXAMPLES_DIR, two_tone_egg, write_two_tone_egg
from neuralfeels_sem.objects.material_object import IGNORE

CLASSES = tuple(DEFAULT_MATERIALS)


def _capsule_mm() -> tuple[trimesh.Trimesh, np.ndarray]:
    """A 120 x 40 mm capsule (in millimetres) and labels: wood where x > 0, else fabric, seam ignored."""
    mesh = trimesh.creation.capsule(height=80.0, radius=20.0, count=[24, 24])
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    x = mesh.triangles_center[:, 0]
    labels = np.where(x > 0, CLASSES.index("wood"), CLASSES.index("fabric"))
    labels[np.abs(x) < 2.0] = IGNORE
    return mesh, labels


def _expected_labels(mm_mesh: trimesh.Trimesh, obj) -> np.ndarray:
    """Labels recomputed from the loaded object's own faces (checks the face order survived)."""
    x_mm = obj.mesh.triangles_center[:, 0] * mm_mesh.extents.max() / obj.mesh.extents.max()
    return np.where(np.abs(x_mm) < 2.0, IGNORE, np.where(x_mm > 0, 3, 2))


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl"])
@pytest.mark.parametrize(
    "label_format", ["npy_int", "npy_str", "json_int", "json_names", "json_classes"]
)
def test_mesh_and_label_formats_round_trip(tmp_path: Path, suffix: str, label_format: str) -> None:
    mesh, labels = _capsule_mm()
    mesh_path = tmp_path / f"capsule{suffix}"
    mesh.export(mesh_path)
    names = np.array([*CLASSES, "ignore"])[labels]
    if label_format == "npy_int":
        np.save(label_path := tmp_path / "labels.npy", labels)
    elif label_format == "npy_str":
        np.save(label_path := tmp_path / "labels.npy", names)
    else:
        label_path = tmp_path / "labels.json"
        data = {
            "json_int": labels.tolist(),
            "json_names": names.tolist(),
            "json_classes": {
                "classes": ["wood", "fabric"],
                "faces": np.select([labels == 3, labels == 2], [0, 1], -1).tolist(),
            },
        }[label_format]
        label_path.write_text(json.dumps(data))
    obj = load_custom_object(str(mesh_path), CLASSES, labels=str(label_path), rescale_to=0.08)
    assert obj.name == "capsule"
    assert obj.mesh.is_watertight and obj.mesh.is_volume
    np.testing.assert_allclose(obj.mesh.extents.max(), 0.08)
    np.testing.assert_allclose(obj.mesh.bounds.mean(axis=0), 0.0, atol=1e-12)
    # STL stores three vertices per face: merging must restore the shared vertices.
    assert len(obj.mesh.vertices) == len(mesh.vertices)
    np.testing.assert_array_equal(obj.face_labels, _expected_labels(mesh, obj))


def test_single_material_and_name(tmp_path: Path) -> None:
    mesh, _ = _capsule_mm()
    mesh.apply_scale(0.001)
    mesh.export(path := tmp_path / "part.stl")
    obj = load_custom_object(str(path), CLASSES, material="metal", name="bolt")
    assert obj.name == "bolt"
    assert (obj.face_labels == CLASSES.index("metal")).all()
    np.testing.assert_allclose(obj.mesh.extents.max(), 0.12)  # no rescale: size kept
    np.testing.assert_allclose(obj.friction, 0.4)
    np.testing.assert_allclose(obj.mass_kg, 700.0 * obj.mesh.volume)


def test_inverted_mesh_is_turned_outwards(tmp_path: Path) -> None:
    mesh, _ = _capsule_mm()
    mesh.invert()
    mesh.export(path := tmp_path / "inside_out.ply")
    obj = load_custom_object(str(path), CLASSES, material="wood")
    assert obj.mesh.volume > 0


def test_sidecar_labels_and_the_shipped_example(tmp_path: Path) -> None:
    mesh_path, labels_path = write_two_tone_egg(tmp_path)
    assert labels_path.name == "two_tone_egg.labels.json"
    # The shipped files are exactly what the generator writes.
    for path in (mesh_path, labels_path):
        assert path.read_bytes() == (EXAMPLES_DIR / path.name).read_bytes()
    obj = load_custom_object(str(mesh_path), CLASSES)
    _, labels, classes = two_tone_egg()
    expected = np.array([CLASSES.index(c) for c in classes] + [IGNORE])[labels]
    np.testing.assert_array_equal(obj.face_labels, expected)
    assert obj.name == "two_tone_egg"


def test_relative_mesh_path_falls_back_to_the_repository(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    obj = load_custom_object("neuralfeels_sem/objects/examples/two_tone_egg.obj", CLASSES)
    assert len(obj.mesh.faces) == 5120


def _one_line_error(kind: type[UserError], match: str, **kwargs) -> None:
    with pytest.raises(kind, match=match) as info:
        load_custom_object(class_names=CLASSES, **kwargs)
    assert "\n" not in str(info.value)


def test_missing_files(tmp_path: Path) -> None:
    _one_line_error(
        DataError,
        "object.mesh=/nonexistent.obj does not exist",
        mesh="/nonexistent.obj",
        material="metal",
    )
    mesh, _ = _capsule_mm()
    mesh.export(path := tmp_path / "m.obj")
    _one_line_error(
        DataError,
        "object.labels=.*nope.npy does not exist",
        mesh=str(path),
        labels=str(tmp_path / "nope.npy"),
    )
    _one_line_error(
        ConfigError, "has no labels: set object.labels.*object.layout_seed=K", mesh=str(path)
    )


def test_not_watertight(tmp_path: Path) -> None:
    mesh, _ = _capsule_mm()
    mesh.update_faces(np.arange(len(mesh.faces)) != 5)
    mesh.export(path := tmp_path / "holey.obj")
    _one_line_error(
        DataError, r"not watertight .*\(3 open edges\)", mesh=str(path), material="plastic"
    )


def test_label_file_of_wrong_length_or_content(tmp_path: Path) -> None:
    mesh, labels = _capsule_mm()
    mesh.export(path := tmp_path / "m.ply")
    np.save(short := tmp_path / "short.npy", labels[:-1])
    _one_line_error(
        DataError,
        f"has {len(labels) - 1} labels but .* has {len(labels)} faces",
        mesh=str(path),
        labels=str(short),
    )
    np.save(big := tmp_path / "big.npy", np.full(len(labels), 4))
    _one_line_error(DataError, "face label 4 is outside -1..3", mesh=str(path), labels=str(big))
    (unknown := tmp_path / "unknown.json").write_text(json.dumps(["glass"] * len(labels)))
    _one_line_error(
        DataError, "'glass', which is not in materials", mesh=str(path), labels=str(unknown)
    )
    (bad := tmp_path / "bad.json").write_text("{not json")
    _one_line_error(DataError, "bad.json is unreadable", mesh=str(path), labels=str(bad))
    (keys := tmp_path / "keys.json").write_text(json.dumps({"faces": [0]}))
    _one_line_error(DataError, "needs exactly the keys", mesh=str(path), labels=str(keys))
    np.save(grid := tmp_path / "grid.npy", np.zeros((len(labels), 2), dtype=int))
    _one_line_error(DataError, "one label per face", mesh=str(path), labels=str(grid))
    (txt := tmp_path / "labels.txt").write_text("0\n")
    _one_line_error(DataError, "must end in .npy or .json", mesh=str(path), labels=str(txt))


def test_bad_config_values(tmp_path: Path) -> None:
    mesh, _ = _capsule_mm()
    mesh.export(path := tmp_path / "m.obj")
    _one_line_error(
        ConfigError, "object.material=metall.*not in materials", mesh=str(path), material="metall"
    )
    _one_line_error(ConfigError, "both set", mesh=str(path), material="metal", labels="x.npy")
    _one_line_error(ConfigError, "rescale_to=-1", mesh=str(path), material="metal", rescale_to=-1.0)


def test_unreadable_or_wrong_kind_of_mesh(tmp_path: Path) -> None:
    (garbage := tmp_path / "garbage.ply").write_bytes(b"ply\nformat nonsense\n")
    _one_line_error(DataError, "garbage.ply is unreadable", mesh=str(garbage), material="metal")
    (step := tmp_path / "part.step").write_text("ISO-10303-21;")
    _one_line_error(DataError, "must be one of .obj, .ply, .stl", mesh=str(step), material="metal")
