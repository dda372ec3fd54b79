"""Every config group composes, every `_target_` resolves, and bad configs fail clearly."""

from __future__ import annotations

import importlib.util

import pytest
from hydra.errors import ConfigCompositionException, HydraException
from hydra.utils import get_method, instantiate
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.utils.paths import SHARED_DATA_DIR
from tests.helpers import CONF_DIR, compose_config, run_cli

GROUPS = (
    "sensor",
    "object",
    "model",
    "classifier",
    "mapping",
    "eval",
    "viz",
    "dataset",
    "task",
    "launcher",
    "experiment",
)
# Options whose plugin is an optional extra.
OPTIONAL = {("launcher", "ray"): "hydra_plugins.hydra_ray_launcher"}
# Options whose objects load third-party data from ../shared/data (absent in a user's clone).
NEEDS_SHARED_DATA = {("experiment", "scanned_objects")}


def group_options() -> list[tuple[str, str]]:
    return [(g, p.stem) for g in GROUPS for p in sorted((CONF_DIR / g).glob("*.yaml"))]


def find_targets(node, path: str = "") -> list[tuple[str, DictConfig]]:
    found = []
    if isinstance(node, DictConfig):
        if "_target_" in node:
            found.append((path, node))
        for key in node:
            if not OmegaConf.is_missing(node, key):
                found.extend(find_targets(node[key], f"{path}.{key}" if path else str(key)))
    return found


@pytest.mark.parametrize(("group", "option"), group_options())
def test_every_option_composes_validates_and_instantiates(group: str, option: str) -> None:
    module = OPTIONAL.get((group, option))
    if module and importlib.util.find_spec(module) is None:
        pytest.skip(f"{group}={option} needs the optional extra providing {module}")
    if (group, option) in NEEDS_SHARED_DATA and not SHARED_DATA_DIR.is_dir():
        pytest.skip(f"{group}={option} loads meshes from {SHARED_DATA_DIR}, which is absent")
    cfg = compose_config([f"{group}={option}"])
    validate_config(cfg)
    for path, node in find_targets(cfg):
        if path == "task":
            assert callable(get_method(node._target_))
        else:
            # Constructors are cheap by contract (no I/O until open()), so build them all.
            assert instantiate(node) is not None, path


def test_hydra_callbacks_instantiate() -> None:
    cfg = compose_config(return_hydra_config=True)
    for name, node in cfg.hydra.callbacks.items():
        assert instantiate(node) is not None, name


def test_unknown_group_option_fails_at_compose() -> None:
    with pytest.raises((ConfigCompositionException, HydraException)):
        compose_config(["sensor=simm"])


def test_unknown_key_fails_at_compose() -> None:
    with pytest.raises(ConfigCompositionException):
        compose_config(["seeed=1"])


def test_wrong_type_fails_at_compose() -> None:
    with pytest.raises(ConfigCompositionException):
        compose_config(["seed=abc"])


@pytest.mark.parametrize(
    "overrides",
    [
        ["seed=-1"],
        ["device=tpu"],
        ["materials=[plastic]"],
        ["task=collect_tactile", "task.edge_press_fraction=1.5"],
        ["task=collect_tactile", "task.edge_tilt_deg=[40,15]"],
        ["task=collect_tactile", "task.feature_press_fraction=-0.1"],
        ["task=train_classifier", "task.lr_schedule=step"],
        ["task=train_classifier", "task.min_lr_ratio=2"],
        ["mapping.mapper.label_vote_min_agreement=0"],
        ["mapping.mapper.label_vote_radius=-0.01"],
        ["mapping.mapper.label_vote_min_support=-1"],
        ["mapping.mapper.label_vote_press_gap=-1"],
        ["mapping.mapper.label_vote_steady_frames=-1"],
        ["mapping.mapper.label_vote_support_radius=-0.01"],
        ["sensor.alternate_axis=[0,0,0]"],
        ["sensor.alternate_every_s=0"],
        ["sensor.alternate_axis=null", "sensor.policy=active"],  # advance needs two axes
        ["sensor.grasp_height=low"],
        ["eval.mesh_match_tolerance_m=0"],
        ["eval.mesh_match_tolerance_m=-0.005"],
        ["eval.mesh_match_tolerance_m=nan"],
    ],
)
def test_out_of_range_value_is_a_config_error(overrides: list[str]) -> None:
    cfg = compose_config(overrides)
    with pytest.raises(ConfigError) as info:
        validate_config(cfg)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "overrides",
    [
        ["sensor.alternate_axis=null"],  # the scripted gait: one axis is fine
        ["sensor.alternate_axis=null", "sensor.policy=active", "sensor.planner.turn=gait"],
    ],
)
def test_one_axis_validates_without_turns_to_advance(overrides: list[str]) -> None:
    validate_config(compose_config(overrides))


def test_cli_out_of_range_exits_2_with_one_line() -> None:
    result = run_cli(["task=info", "seed=-5"])
    assert result.returncode == 2, result.stderr
    error_lines = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert error_lines == ["error: invalid config: seed=-5 must be >= 0"]
    assert "Traceback" not in result.stderr


@pytest.mark.slow  # Hydra's own message for an unknown key; the refusal path is tested above
def test_cli_typo_fails_with_hydra_message() -> None:
    result = run_cli(["task=info", "objct=plushie"])
    assert result.returncode != 0
    assert "objct" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow  # Hydra lists every group's options by re-reading the config store: 7 s
def test_cli_help_lists_the_config_groups() -> None:
    help_result = run_cli(["--help"])
    assert help_result.returncode == 0
    for group in ("sensor", "object", "model", "task", "launcher"):
        assert f"{group}:" in help_result.stdout


def test_cli_cfg_job_prints_the_composed_config() -> None:
    cfg_result = run_cli(["--cfg", "job"])
    assert cfg_result.returncode == 0
    assert "materials:" in cfg_result.stdout


def test_the_default_sim_motion_is_the_one_bench_and_rig_touches_use() -> None:
    # bench/finger_contacts and bench/rig_touches build the rig from SimSensorConfig's defaults;
    # they must move the object as `sensor=sim` does.
    from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
    from neuralfeels_sem.sim.rig import SimRig
    from tests.sim.shapes import two_material_sphere

    sensor = compose_config([]).sensor
    motion = SimSensorConfig().rig_motion()
    assert motion == {
        "axis": list(sensor.rotation_axis),
        "speed_deg_s": sensor.rotation_speed_deg_s,
        "wobble_deg": sensor.wobble_deg,
        "alternate_axis": list(sensor.alternate_axis),
        "alternate_every_s": sensor.alternate_every_s,
        "grasp_height": sensor.grasp_height,
    }
    rig = SimRig(two_material_sphere(0.04), **motion)
    rig.open()
    assert len(rig.trajectory.axes) == 2


@pytest.mark.parametrize(
    ("overrides", "reach"),
    [
        ([], 0.01),  # sim at its offline pace
        (["sensor.pace=realtime"], 0.01),
        (["sensor=real"], 0.01),  # a rig streams
        (["sensor=real", "sensor.pace=offline"], 0.01),
        (["sensor.pace=realtime", "mapping.mapper.label_vote_press_reach=null"], None),
        (["mapping.mapper.label_vote_press_reach=0.02"], 0.02),
    ],
)
def test_the_press_reach_is_1_cm_at_every_pace_unless_set(overrides: list[str], reach) -> None:
    assert compose_config(overrides).mapping.mapper.label_vote_press_reach == reach


@pytest.mark.parametrize(("pace", "reach"), [("offline", None), ("realtime", 0.01)])
def test_a_config_recorded_with_the_pace_resolver_still_resolves(pace: str, reach) -> None:
    """Runs recorded while the reach depended on the pace keep the interpolation in their
    .hydra/config.yaml; resuming or scoring them must still read it."""
    compose_config()  # registers the resolvers
    recorded = OmegaConf.create(
        {
            "sensor": {"pace": pace},
            "reach": "${at_pace:${oc.select:sensor.pace,offline},null,0.01}",
        }
    )
    assert recorded.reach == reach
