"""object=random: generated objects are deterministic, checked, redrawn on failure, configurable."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hydra.errors import InstantiationException
from hydra.utils import instantiate

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS, IGNORE
from neuralfeels_sem.objects import layout_draw as L
from neuralfeels_sem.objects import random_object as R
from neuralfeels_sem.objects.random_shapes import FAMILIES
from tests.helpers import compose_config

CLASSES = tuple(DEFAULT_MATERIALS)


def test_same_seed_same_object_other_seed_other_object() -> None:
    first = R.build_arrays(3, "boxy", CLASSES)
    again = R.build_arrays(3, "boxy", CLASSES)
    for a, b in zip(first[:3], again[:3]):
        np.testing.assert_array_equal(a, b)
    assert first[3] == again[3]
    other = R.build_arrays(4, "boxy", CLASSES)
    assert other[0].shape != first[0].shape or not np.allclose(other[0], first[0])
    # The family is drawn from the seed alone, so a redraw never changes it.
    assert R.family_of(1003, None) == R.family_of(1003, None)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_family_builds_a_watertight_object_of_two_to_four_materials(family: str) -> None:
    obj = R.make_random_object(11, CLASSES, family=family)
    assert obj.mesh.is_watertight and obj.mesh.volume > 0
    size = float(obj.mesh.extents.max())
    assert R.SIZE_RANGE_M[0] <= size <= R.SIZE_RANGE_M[1], size
    present = set(np.unique(obj.face_labels[obj.face_labels != IGNORE]))
    assert 2 <= len(present) <= 4
    assert {CLASSES[k] for k in present} == set(obj.generation["materials"])
    areas = obj.area_by_material()
    assert all(areas[m] >= L.MIN_PATCH_AREA_M2 for m in obj.generation["materials"])
    assert 0 < areas["ignore"] < (1 - L.MIN_LABELLED_SHARE) * obj.mesh.area  # seams, resting face
    assert obj.generation["family"] == family and obj.name == "random_11"
    assert np.allclose(obj.mesh.bounds.mean(axis=0), 0.0, atol=1e-9)


def test_a_draw_failing_its_checks_is_redrawn_from_the_next_sub_seed(monkeypatch) -> None:
    drawn: list[int] = []
    real_draw, real_problems = R.draw_object, R.problems

    def draw(seed, sub_seed, *args):
        drawn.append(sub_seed)
        return real_draw(seed, sub_seed, *args)

    def problems(*args):  # the first two draws fail, whatever they are
        return ["forced failure"] if drawn[-1] < 2 else real_problems(*args)

    monkeypatch.setattr(R, "draw_object", draw)
    monkeypatch.setattr(R, "problems", problems)
    vertices, faces, names, record = R.build_arrays(5, "boxy", CLASSES)
    assert drawn[:3] == [0, 1, 2] and record["sub_seed"] == drawn[-1] >= 2
    mesh, expected_names, _ = real_draw(5, record["sub_seed"], "boxy", CLASSES)
    np.testing.assert_array_equal(vertices, mesh.vertices)
    np.testing.assert_array_equal(names, expected_names)


def test_an_object_that_never_passes_is_an_error_not_accepted(monkeypatch) -> None:
    monkeypatch.setattr(L, "MAX_SUB_SEEDS", 2)
    monkeypatch.setattr(L, "MIN_PATCH_AREA_M2", 1.0)  # no patch is a square metre
    with pytest.raises(DataError, match=r"object.seed=5 .* failed its checks in 2 draws") as info:
        R.build_arrays(5, "boxy", CLASSES)
    assert "\n" not in str(info.value)


def test_checks_catch_holes_missing_materials_and_slivers() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.04)
    names = np.where(mesh.triangles_center[:, 2] > 0, "wood", "metal")
    assert R.problems(mesh, names, ["wood", "metal"]) == []
    assert "material ['fabric']" in R.problems(mesh, names, ["wood", "metal", "fabric"])[0]
    names[0] = "fabric"  # one face: far below the minimum patch
    assert any("a patch below" in p for p in R.problems(mesh, names, ["wood", "metal"]))
    open_mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[1:], process=False)
    assert "not watertight" in R.problems(open_mesh, names[1:], ["wood", "metal"])


def test_unknown_family_or_material_is_a_one_line_config_error() -> None:
    with pytest.raises(ConfigError, match=r"object.family='teapot' is unknown: pick one of \["):
        R.make_random_object(0, CLASSES, family="teapot")
    with pytest.raises(ConfigError, match=r"object.materials has \['glass'\], not in materials="):
        R.make_random_object(0, CLASSES, materials=["wood", "glass"])
    with pytest.raises(ConfigError, match="needs at least two different materials"):
        R.make_random_object(0, CLASSES, materials=["wood", "wood"])


def test_config_composes_and_instantiates_with_a_material_subset() -> None:
    cfg = compose_config(
        ["object=random", "object.seed=7", "object.family=rimmed", "object.materials=[wood,metal]"]
    )
    validate_config(cfg)
    assert cfg.object.name == "random_7"
    obj = instantiate(cfg.object)
    assert set(obj.generation["materials"]) == {"wood", "metal"}
    assert obj.class_names == CLASSES
    bad = compose_config(["object=random", "object.family=teapot"])
    with pytest.raises(InstantiationException) as info:
        instantiate(bad.object)
    assert isinstance(info.value.__cause__, ConfigError)
    with pytest.raises(ConfigError, match=r"object.seed=-1 must be >= 0"):
        validate_config(compose_config(["object=random", "object.seed=-1"]))


def swept(cfg, key: str) -> list:
    """The values a composed experiment's sweeper runs `key` over."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    value = cfg.hydra.sweeper.params[key]
    parsed = OverridesParser.create().parse_overrides([f"{key}={value}"])
    return list(parsed[0].sweep_iterator())


def test_unseen_objects_experiment_sweeps_the_twenty_evaluation_seeds() -> None:
    cfg = compose_config(["experiment=unseen_objects"], return_hydra_config=True)
    assert cfg.object._target_.endswith("make_random_object") and cfg.task.name == "map"
    assert swept(cfg, "object.seed") == list(range(1000, 1020))
    assert swept(cfg, "seed") == [0, 1]  # two mapping seeds per object


def test_development_objects_experiment_mirrors_the_evaluation_set_below_it() -> None:
    """experiment=development_objects: as many objects and mapping seeds as the evaluation
    set, every object a development seed (the same range check that guards training data)."""
    from neuralfeels_sem.objects.random_object import EVALUATION_SEEDS_FROM, development_seeds

    dev = compose_config(["experiment=development_objects"], return_hydra_config=True)
    held = compose_config(["experiment=unseen_objects"], return_hydra_config=True)
    assert dev.object._target_ == held.object._target_ and dev.task.name == "map"
    objects = swept(dev, "object.seed")
    assert objects == development_seeds(f"{objects[0]}-{objects[-1]}")
    assert max(objects) < EVALUATION_SEEDS_FROM
    assert len(objects) == len(swept(held, "object.seed"))
    assert swept(dev, "seed") == swept(held, "seed")


def test_development_seed_ranges_refuse_the_evaluation_set() -> None:
    from neuralfeels_sem.objects.random_object import development_seeds

    assert development_seeds("7") == [7]
    assert development_seeds("20-23") == [20, 21, 22, 23]
    with pytest.raises(ValueError, match="evaluation set"):
        development_seeds("990-1000")
    with pytest.raises(ValueError, match="write K or A-B"):
        development_seeds("twenty")
