"""Drawn layouts on a given mesh: checked, redrawn from the next sub-seed, never accepted failing;
and object=custom object.layout_seed=K, which paints one onto the user's mesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects import layout_draw as L
from neuralfeels_sem.objects.custom import load_custom_object
from neuralfeels_sem.objects.example_files import EXAMPLES_DIR

CLASSES = tuple(DEFAULT_MATERIALS)
EGG = str(EXAMPLES_DIR / "two_tone_egg.obj")


def test_layout_checks_catch_missing_materials_slivers_and_unlabelled_surface() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.04)
    names = np.where(mesh.triangles_center[:, 2] > 0, "wood", "metal")
    assert L.layout_problems(mesh, names, ["wood", "metal"]) == []
    assert "material ['fabric']" in L.layout_problems(mesh, names, ["wood", "metal", "fabric"])[0]
    speck = names.copy()
    speck[0] = "fabric"  # one face: far below the minimum patch
    assert any("a patch below" in p for p in L.layout_problems(mesh, speck, ["wood", "metal"]))
    mostly_ignored = np.where(mesh.triangles_center[:, 2] > -0.02, "ignore", "wood")
    assert any(
        "% of the surface labelled" in p for p in L.layout_problems(mesh, mostly_ignored, ["wood"])
    )


def test_a_layout_failing_its_checks_is_redrawn_from_the_next_sub_seed(monkeypatch) -> None:
    mesh = trimesh.creation.capsule(height=0.06, radius=0.02, count=[32, 32])
    checked: list[int] = []
    real = L.layout_problems

    def problems(*args):  # the first two draws fail, whatever they are
        checked.append(len(checked))
        return ["forced failure"] if len(checked) <= 2 else real(*args)

    monkeypatch.setattr(L, "layout_problems", problems)
    names, record = L.draw_on_mesh(mesh, 4, CLASSES, "test mesh")
    assert record["sub_seed"] >= 2 and record["layout_seed"] == 4
    monkeypatch.setattr(L, "layout_problems", real)
    stream = [4, record["sub_seed"], L.shape_key(mesh)]
    layout = L.draw_layout(mesh, CLASSES, np.random.default_rng(stream))
    np.testing.assert_array_equal(names, L.paint(mesh, layout))
    assert set(names) - {"ignore"} == set(record["materials"])


def test_a_mesh_no_layout_fits_is_a_one_line_error(monkeypatch) -> None:
    monkeypatch.setattr(L, "MAX_SUB_SEEDS", 2)
    tiny = trimesh.creation.icosphere(subdivisions=2, radius=0.005)  # 3 cm^2 in all
    with pytest.raises(
        DataError, match=r"tiny: no material layout from seed 1 .* in 2 draws"
    ) as info:
        L.draw_on_mesh(tiny, 1, CLASSES, "tiny")
    assert "\n" not in str(info.value) and "object.layout_seed" in str(info.value)


def test_custom_mesh_with_a_layout_seed_gets_a_checked_deterministic_layout() -> None:
    obj = load_custom_object(EGG, CLASSES, layout_seed=3, rescale_to=0.09)
    again = load_custom_object(EGG, CLASSES, layout_seed=3, rescale_to=0.09)
    other = load_custom_object(EGG, CLASSES, layout_seed=4, rescale_to=0.09)
    np.testing.assert_array_equal(obj.face_labels, again.face_labels)
    assert not np.array_equal(obj.face_labels, other.face_labels)
    record = obj.layout
    assert record["mesh"] == "two_tone_egg" and record["layout_seed"] == 3
    assert record["size_m"] == pytest.approx(0.09)
    present = {CLASSES[k] for k in np.unique(obj.face_labels) if k >= 0}
    assert present == set(record["materials"]) and 2 <= len(present) <= 4
    areas = obj.area_by_material()
    assert all(areas[m] >= L.MIN_PATCH_AREA_M2 for m in record["materials"])


@pytest.mark.parametrize(
    "options",
    [{"material": "wood"}, {"labels": str(EXAMPLES_DIR / "two_tone_egg.labels.json")}],
)
def test_layout_seed_with_labels_or_material_is_a_one_line_config_error(options: dict) -> None:
    with pytest.raises(
        ConfigError, match=r"object.layout_seed=2 and object\.\w+=.* are both set: pick one"
    ):
        load_custom_object(EGG, CLASSES, layout_seed=2, **options)


def test_ycb_scan_takes_a_drawn_layout(shared_data: Path) -> None:
    path = shared_data / "ycb" / "TomatoSoupCan" / "model.obj"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    obj = load_custom_object(str(path), CLASSES, layout_seed=0)
    assert obj.mesh.is_watertight
    assert obj.layout["mesh"] == "model" and len(obj.layout["materials"]) >= 2
    assert (obj.face_labels >= 0).mean() > L.MIN_LABELLED_SHARE


def test_shape_key_tells_meshes_apart_and_ignores_where_the_mesh_sits() -> None:
    mesh = trimesh.creation.capsule(height=0.06, radius=0.02, count=[32, 32])
    moved = mesh.copy()
    moved.apply_translation([0.1, -0.2, 0.3])
    larger = mesh.copy()
    larger.apply_scale(1.01)
    assert L.shape_key(moved) == L.shape_key(mesh) != L.shape_key(larger)


def test_a_negative_layout_seed_is_a_one_line_config_error() -> None:
    with pytest.raises(ConfigError, match=r"object.layout_seed=-3 must be an integer >= 0"):
        load_custom_object(EGG, CLASSES, layout_seed=-3)
