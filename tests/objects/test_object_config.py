"""conf/object/: every option instantiates a MaterialObject over the configured classes."""

from __future__ import annotations

import pytest
from hydra.errors import InstantiationException
from hydra.utils import instantiate

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.configs.object import SHIPPED_OBJECTS, TACTILE_DATA_OBJECTS
from neuralfeels_sem.configs.sensor_sim import CollectTactileTaskConfig
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.objects.material_object import MaterialObject
from tests.helpers import CONF_DIR, compose_config, run_cli


def test_every_shipped_object_has_a_yaml() -> None:
    assert {p.stem for p in CONF_DIR.glob("object/*.yaml")} == {
        *SHIPPED_OBJECTS,
        "custom",
        "random",
    }


@pytest.mark.parametrize("option", ["plushie", "custom"])
def test_instantiate_returns_a_material_object_over_the_materials(option: str) -> None:
    cfg = compose_config([f"object={option}", "materials=[wood,metal,plastic,fabric,glass]"])
    validate_config(cfg)
    obj = instantiate(cfg.object)
    assert isinstance(obj, MaterialObject)
    assert obj.class_names == ("wood", "metal", "plastic", "fabric", "glass")
    assert obj.name == cfg.object.name


def test_custom_name_defaults_to_the_file_stem() -> None:
    cfg = compose_config(
        ["object=custom", "object.mesh=/data/scans/mug_01.ply", "object.material=metal"]
    )
    assert cfg.object.name == "mug_01"
    cfg = compose_config(["object=custom", "object.mesh=/data/scans/mug_01.ply", "object.name=mug"])
    assert cfg.object.name == "mug"


def test_object_missing_a_material_is_a_config_error() -> None:
    cfg = compose_config(["object=plushie", "materials=[plastic,metal,wood]"])
    # Hydra wraps what a target raises; the ConfigError is the cause.
    with pytest.raises(InstantiationException) as info:
        instantiate(cfg.object)
    assert isinstance(info.value.__cause__, ConfigError)
    assert "'fabric'" in str(info.value.__cause__)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["object=plushie", "object.name=plushy"], "object.name='plushy' is not a shipped object"),
        (["object=custom", "object.rescale_to=0"], "object.rescale_to=0.0 must be in"),
        (["object=custom", "object.labels=a.npy", "object.material=metal"], "are both set"),
        (["object=custom", "object.layout_seed=1", "object.material=metal"], "are both set"),
        (["object=custom", "object.layout_seed=-1"], "object.layout_seed=-1 must be >= 0"),
        (
            ["object=plushie", "object.aruco.markers=[{id:3,pose:[0,0,0]}]"],
            r"object.aruco.markers\[0\].pose needs 6 values",
        ),
        (
            [
                "object=custom",
                "object.aruco.markers=[{id:3,pose:[0,0,0,0,0,0]},{id:3,pose:[0,0,0,0,0,0]}]",
            ],
            r"object.aruco.markers\[1\].id=3 is listed twice",
        ),
        (["object=plushie", "object.aruco.marker_length_m=0"], "object.aruco.marker_length_m=0.0"),
        (["object=plushie", "object.aruco.markers=[{id:-1,pose:[0,0,0,0,0,0]}]"], "must be >= 0"),
    ],
)
def test_bad_values_fail_validation_with_one_line(overrides: list[str], message: str) -> None:
    cfg = compose_config(overrides)
    with pytest.raises(ConfigError, match=message) as info:
        validate_config(cfg)
    assert "\n" not in str(info.value)


@pytest.mark.slow  # the same refusal path as test_configs' CLI test; values checked in-process above
def test_cli_bad_object_values_exit_with_one_line() -> None:
    result = run_cli(["task=info", "object=custom", "object.rescale_to=-1"])
    assert result.returncode == 2, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert errors == [
        "error: invalid config: object.rescale_to=-1.0 must be in (0, 1] metres, or null"
    ]
    unknown = run_cli(["task=info", "object=plushy"])
    assert unknown.returncode != 0
    assert "object/plushy" in unknown.stderr and "Traceback" not in unknown.stderr


def test_shipped_objects_have_no_marker_layout_and_a_layout_still_instantiates() -> None:
    for name in SHIPPED_OBJECTS:
        assert compose_config([f"object={name}"]).object.aruco.markers == []
    cfg = compose_config(
        [
            "object=custom",
            "object.aruco.marker_length_m=0.03",
            "object.aruco.markers=[{id:3,pose:[0.03,0,0,0,1.5708,0]},{id:7,pose:[0,0,0.03,0,0,0]}]",
        ]
    )
    validate_config(cfg)
    assert [m.id for m in cfg.object.aruco.markers] == [3, 7]
    assert isinstance(instantiate(cfg.object), MaterialObject)  # the mesh ignores the layout


def test_tactile_data_objects_exclude_the_later_objects() -> None:
    # The shipped classifier was trained on touches of these seven; objects added since
    # (patchwork, kitchen_tool) must not change task=collect_tactile's data set.
    task = compose_config(["task=collect_tactile"]).task
    assert list(task.library_objects) == list(TACTILE_DATA_OBJECTS)
    assert CollectTactileTaskConfig().library_objects == list(TACTILE_DATA_OBJECTS)
    assert set(TACTILE_DATA_OBJECTS) < set(SHIPPED_OBJECTS)
    assert {"patchwork", "kitchen_tool"}.isdisjoint(TACTILE_DATA_OBJECTS)
