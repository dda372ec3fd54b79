"""One source per setting: the schema dataclasses hold the only defaults, the yaml files do
not repeat them (config.yaml and every group with a schema), no constructor keeps a default
of its own, and every setting is read."""

from __future__ import annotations

import dataclasses
import functools
import inspect
import re
import typing

import pytest
import torch
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from neuralfeels_sem.configs import register_configs, to_config
from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.configs.dataset import TactileDatasetConfig
from neuralfeels_sem.configs.eval import EvalConfig
from neuralfeels_sem.configs.mapping import MappingConfig
from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.configs.viz import VizConfig
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.fields.hash_grid import HashGridConfig, HashGridEncoding
from neuralfeels_sem.fields.optim import FieldAdam, OptimizerConfig
from neuralfeels_sem.fields.semantic_field import SemanticField, SemanticFieldConfig
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig
from neuralfeels_sem.utils.paths import REPO_DIR
from tests.helpers import CONF_DIR, compose_config
from tests.mapping.synthetic import small_field, sphere_frames

# (config group node, its schema, what the yaml's interpolations give by default)
GROUPS = [
    ("mapping", MappingConfig, MappingConfig()),
    ("model", SemanticFieldConfig, SemanticFieldConfig(num_classes=len(DEFAULT_MATERIALS))),
    ("eval", EvalConfig, EvalConfig()),
    ("viz", VizConfig, VizConfig()),
    (
        "classifier",
        EfficientNetClassifierConfig,
        EfficientNetClassifierConfig(class_names=DEFAULT_MATERIALS),
    ),
    ("sensor", SimSensorConfig, SimSensorConfig()),
    ("dataset", TactileDatasetConfig, TactileDatasetConfig()),
]


@pytest.mark.parametrize(("key", "schema", "defaults"), GROUPS, ids=[g[0] for g in GROUPS])
def test_the_composed_default_config_is_the_dataclass_defaults(key, schema, defaults) -> None:
    cfg = compose_config()
    assert to_config(schema, cfg[key]) == defaults
    assert list(cfg.materials) == DEFAULT_MATERIALS


def _leaves(node, path: str = ""):
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _leaves(value, f"{path}.{key}" if path else key)
    else:  # a value or a list
        yield path, node


# The yaml files that extend a schema directly (config.yaml extends RootConfig). A variant
# that extends another option of its group (model/semantic_sdf_paper.yaml) is a choice of
# other values by design.
SCHEMA_GROUPS = ("mapping", "model", "eval", "viz", "classifier", "sensor", "dataset", "task")
YAMLS = ["config.yaml"] + sorted(
    str(p.relative_to(CONF_DIR))
    for g in SCHEMA_GROUPS
    for p in (CONF_DIR / g).rglob("*.yaml")
    if "/schema/" in p.read_text()
)


def _schema_node(name: str, defaults: list):
    """The schema a conf/ yaml extends (its `/schema/...@_here_` entry), as a config node."""
    extends = [d for d in defaults if isinstance(d, str) and "schema/" in d]
    assert len(extends) == 1, f"{name} extends no schema (or several): {defaults}"
    schema = extends[0].lstrip("/").split("@")[0]
    return ConfigStore.instance().load(f"{schema}.yaml").node


@pytest.mark.parametrize("name", YAMLS)
def test_the_yaml_sets_only_what_the_schema_cannot_know(name: str) -> None:
    """No default is repeated in conf/: a yaml only interpolates (class count, seed,
    materials, device) or fills what its schema leaves open (a task's `_target_`)."""
    register_configs()
    raw = OmegaConf.to_container(OmegaConf.load(CONF_DIR / name), resolve=False)
    node = _schema_node(name, raw.pop("defaults"))
    for path, value in _leaves(raw):
        interpolates = isinstance(value, str) and value.startswith("${")
        left_open = OmegaConf.is_missing(node, path) if "." not in path else False
        assert interpolates or left_open, (
            f"{name}: {path}={value!r} repeats or overrides its schema"
        )


# ---------------------------------------------------------------- constructor defaults
CONSTRUCTORS = [
    (FieldAdam, OptimizerConfig),
    (OnlineMapper, MapperConfig),
    (SemanticField, SemanticFieldConfig),
    (HashGridEncoding, HashGridConfig),
    (PoseTracker, TrackerConfig),
    (TactileDepth, TactileDepthConfig),
]


@pytest.mark.parametrize(("cls", "schema"), CONSTRUCTORS, ids=[c.__name__ for c, _ in CONSTRUCTORS])
def test_no_constructor_default_differs_from_its_config(cls, schema) -> None:
    """A constructor takes its config; an argument named like a setting (FieldAdam's, for
    torch.optim's calling convention) has no default or the config's."""
    defaults = {f.name: getattr(schema(**_required(schema)), f.name) for f in _fields(schema)}
    for name, param in inspect.signature(cls.__init__).parameters.items():
        if name in defaults and param.default is not inspect.Parameter.empty:
            default = param.default
            default = list(default) if isinstance(default, tuple) else default
            assert default == defaults[name], f"{cls.__name__}({name}={param.default!r})"


def _fields(schema) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(schema) if not f.name.startswith("_")]


def _required(schema) -> dict:
    return {"num_classes": 2} if schema is SemanticFieldConfig else {}


# ---------------------------------------------------------------- every setting is read
class Recording:
    """Stands in for a config and records which settings (dotted paths) are read."""

    def __init__(self, config, read: set[str], prefix: str = "") -> None:
        self._config, self._read, self._prefix = config, read, prefix

    def __getattr__(self, name: str):
        value = getattr(self._config, name)
        path = self._prefix + name
        self._read.add(path)
        if dataclasses.is_dataclass(value):
            return Recording(value, self._read, path + ".")
        return value


def settings(schema, prefix: str = "") -> set[str]:
    """Every setting of a schema, nested blocks as dotted paths (Hydra keys `_x_` aside)."""
    types = typing.get_type_hints(schema)
    out = set()
    for f in _fields(schema):
        if dataclasses.is_dataclass(types[f.name]):
            out |= settings(types[f.name], f"{prefix}{f.name}.")
        else:
            out.add(prefix + f.name)
    return out


def test_every_mapper_setting_is_read_by_the_mapper_or_its_parts() -> None:
    read: set[str] = set()
    # surprise: the policy that reads min_steps_per_frame too
    config = MapperConfig(
        num_classes=2, camera_rays=16, tactile_rays=8, material_points=8, steps_policy="surprise"
    )
    torch.manual_seed(0)
    mapper = OnlineMapper(
        Recording(config, read),
        small_field(log2_table_size=10),
        functools.partial(FieldAdam, lr=1e-3),
        "cpu",
    )
    frames = sphere_frames(2, touches_per_frame=2)
    for frame, labels in frames:  # the warm-up frame, then one the steps policy sizes
        mapper.add_frame(frame, labels)
    assert settings(MapperConfig) - read == set()


@pytest.mark.parametrize(
    ("build", "schema"),
    [
        (lambda c: SemanticField(c, bound=0.1), SemanticFieldConfig),
        (HashGridEncoding, HashGridConfig),
        (PoseTracker, TrackerConfig),
        (TactileDepth, TactileDepthConfig),
    ],
    ids=["SemanticField", "HashGridEncoding", "PoseTracker", "TactileDepth"],
)
def test_every_setting_is_read_by_its_class(build, schema) -> None:
    read: set[str] = set()
    config = schema(**_required(schema))
    if schema is SemanticFieldConfig:
        config = dataclasses.replace(config, encoding=HashGridConfig(log2_table_size=8))
    build(Recording(config, read))
    assert settings(schema) - read == set()


def test_every_optimizer_setting_is_an_argument_of_its_target() -> None:
    params = inspect.signature(FieldAdam.__init__).parameters
    assert {f.name for f in _fields(OptimizerConfig)} <= set(params)


def test_every_mapping_setting_is_read_by_the_map_task() -> None:
    """`mapping.<key>` of MappingConfig's own keys is read where the task wires the run."""
    tasks = REPO_DIR / "neuralfeels_sem" / "tasks"
    source = (tasks / "map.py").read_text() + (tasks / "build.py").read_text()
    for f in _fields(MappingConfig):
        assert re.search(rf"cfg\.mapping\.{f.name}\b", source), f"mapping.{f.name} is read nowhere"
