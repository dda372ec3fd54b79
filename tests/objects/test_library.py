"""The shipped objects: closed, hand-sized, centred, labelled as described, deterministic."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.configs.object import SHIPPED_OBJECTS
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import build_arrays, list_objects, make_object
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.objects.procedural import RECIPES

CLASSES = tuple(DEFAULT_MATERIALS)
SINGLE = {
    "fabric_toy": "fabric",
    "yarn_ball": "fabric",
    "candle_holder": "wood",
    "powder_shaker": "metal",
    "plastic_toy": "plastic",
}


def test_config_list_matches_the_library() -> None:
    assert set(SHIPPED_OBJECTS) == set(RECIPES) == set(list_objects())
    assert all(isinstance(d, str) and d for d in list_objects().values())


@pytest.mark.parametrize("name", sorted(RECIPES))
def test_object_is_closed_hand_sized_centred_and_labelled(name: str) -> None:
    obj = make_object(name, CLASSES)
    assert isinstance(obj, MaterialObject) and obj.name == name
    mesh = obj.mesh
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume
    assert len(mesh.split(only_watertight=False)) == 1
    # Hand-sized: 5-12 cm; the kitchen tool is 13.7 cm long (the rig turns it, see its tests).
    assert 0.05 <= mesh.extents.max() <= (0.14 if name == "kitchen_tool" else 0.12)
    np.testing.assert_allclose(mesh.bounds.mean(axis=0), 0.0, atol=1e-9)
    assert 5_000 <= len(mesh.faces) <= 30_000
    # Fine enough for a 1 mm tactile renderer: edges of a couple of millimetres at most.
    assert mesh.edges_unique_length.max() < 0.004
    labels = obj.face_labels
    assert labels.shape == (len(mesh.faces),)
    assert set(np.unique(labels)) <= {IGNORE, *range(len(CLASSES))}
    assert obj.class_names == CLASSES
    assert 0.005 < obj.mass_kg < 0.5 and 0.2 < obj.friction < 1.5


@pytest.mark.parametrize(("name", "material"), sorted(SINGLE.items()))
def test_single_material_objects(name: str, material: str) -> None:
    areas = make_object(name, CLASSES).area_by_material()
    total = sum(areas.values())
    assert areas[material] / total > 0.7
    assert all(a == 0.0 for key, a in areas.items() if key not in (material, "ignore"))


def _components(mesh: trimesh.Trimesh, mask: np.ndarray) -> list[float]:
    """Areas (cm^2) of the face-connected components of the faces in `mask`, largest first."""
    adjacency = mesh.face_adjacency[mask[mesh.face_adjacency].all(axis=1)]
    groups = trimesh.graph.connected_components(adjacency, nodes=np.flatnonzero(mask), min_len=1)
    return sorted((mesh.area_faces[g].sum() * 1e4 for g in groups), reverse=True)


def test_plushie_has_fabric_body_plastic_eyes_nose_and_tag() -> None:
    obj = make_object("plushie", CLASSES)
    areas = obj.area_by_material()
    assert areas["fabric"] / sum(areas.values()) > 0.85
    assert areas["metal"] == areas["wood"] == 0.0
    plastic = _components(obj.mesh, obj.face_labels == CLASSES.index("plastic"))
    assert len(plastic) == 4  # two eyes, the nose, the tag
    tag, *small = plastic
    assert 3.0 < tag < 8.0  # a fingertip-sized flat tag
    assert all(0.3 < a < 2.5 for a in small)
    # The tag is on the back (-x), the eyes and nose on the front (+x).
    back = obj.mesh.triangles_center[obj.face_labels == 0][:, 0] < 0
    assert 0.4 < back.mean() < 0.9


def test_patched_toy_has_touchable_fabric_and_plastic() -> None:
    obj = make_object("patched_toy", CLASSES)
    areas = obj.area_by_material()
    total = sum(areas.values())
    assert 0.3 <= areas["fabric"] / total <= 0.5
    assert 0.3 <= areas["plastic"] / total <= 0.6
    # One patch, and every region is many fingertips (a DIGIT gel is about 3 cm^2) big.
    assert len(_components(obj.mesh, obj.face_labels == CLASSES.index("fabric"))) == 1
    assert min(areas["fabric"], areas["plastic"]) * 1e4 > 30
    # Same geometry as the plastic toy: only the labels differ.
    plain = make_object("plastic_toy", CLASSES)
    np.testing.assert_array_equal(plain.mesh.faces, obj.mesh.faces)


def test_mass_from_body_material_and_area_weighted_friction() -> None:
    obj = make_object("patched_toy", CLASSES)
    areas = obj.area_by_material()
    np.testing.assert_allclose(obj.mass_kg, 350.0 * obj.mesh.volume)  # hollow plastic body
    expected = (0.6 * areas["plastic"] + 1.0 * areas["fabric"]) / (
        areas["plastic"] + areas["fabric"]
    )
    np.testing.assert_allclose(obj.friction, expected)


def test_seam_between_materials_is_ignored() -> None:
    obj = make_object("patched_toy", CLASSES)
    a, b = obj.mesh.face_adjacency.T
    la, lb = obj.face_labels[a], obj.face_labels[b]
    # No labelled face touches a face of another material: an ignored band sits between.
    assert not ((la != lb) & (la != IGNORE) & (lb != IGNORE)).any()


def test_labels_follow_the_class_order_and_need_their_classes() -> None:
    a = make_object("plushie", CLASSES)
    b = make_object("plushie", ("fabric", "plastic", "glass"))
    names_a = np.array([*CLASSES, "ignore"])[a.face_labels]
    names_b = np.array(["fabric", "plastic", "glass", "ignore"])[b.face_labels]
    np.testing.assert_array_equal(names_a, names_b)
    with pytest.raises(ConfigError) as info:
        make_object("plushie", ("plastic", "metal", "wood"))
    assert "'fabric'" in str(info.value) and "\n" not in str(info.value)


def test_unknown_object_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="plushy") as info:
        make_object("plushy", CLASSES)
    assert "\n" not in str(info.value)


def test_generation_is_deterministic_and_copies_are_independent() -> None:
    first = make_object("powder_shaker", CLASSES)
    vertices, faces, names, _ = build_arrays("powder_shaker")  # no cache of any kind
    np.testing.assert_array_equal(first.mesh.vertices, vertices)
    np.testing.assert_array_equal(first.mesh.faces, faces)
    np.testing.assert_array_equal(np.array([*CLASSES, "ignore"])[first.face_labels], names)
    first.mesh.apply_translation([1.0, 0.0, 0.0])
    second = make_object("powder_shaker", CLASSES)
    np.testing.assert_allclose(second.mesh.bounds.mean(axis=0), 0.0, atol=1e-9)


def test_labels_at_and_samples_agree_with_face_labels() -> None:
    obj = make_object("patched_toy", CLASSES)
    _, faces, labels = obj.sample_surface(2000, seed=3)
    np.testing.assert_array_equal(labels, obj.face_labels[faces])
    # A face's centroid is closest to that face, so looking it up returns its own label.
    faces = np.random.default_rng(0).choice(len(obj.mesh.faces), 300, replace=False)
    np.testing.assert_array_equal(
        obj.labels_at(obj.mesh.triangles_center[faces]), obj.face_labels[faces]
    )
    areas = obj.area_by_material()
    assert abs(sum(areas.values()) - obj.mesh.area) < 1e-12
