"""Runs judged against today's defaults: a default changed since a run makes it a setting."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from neuralfeels_sem.eval.results_drift import (
    current_overrides,
    drift,
    group_overrides,
    redundant,
    same_value,
    show,
)
from neuralfeels_sem.utils.nested import flatten
from tests.eval.test_results_page import cells, generate, run_metrics, section
from tests.helpers import compose_config
from tests.viz.test_sweep_plots import write_job


def test_flatten_keeps_lists_as_leaves() -> None:
    tree = {"a": {"b": 1, "c": {"d": [1, 2]}}, "e": None}
    assert flatten(tree) == {"a.b": 1, "a.c.d": [1, 2], "e": None}


@pytest.mark.parametrize(
    ("a", "b", "same"),
    [(20, 20.0, True), (10.0, 20.0, False), (True, 1, False), ([1, 2], [1.0, 2.0], True),
     ("${seed}", "${seed}", True), (None, 0, False)],
)  # fmt: skip
def test_values_compare_as_config_values(a, b, same: bool) -> None:
    assert same_value(a, b) is same


def test_drift_skips_overridden_ignored_and_one_sided_keys() -> None:
    recorded = {
        "seed": 3,
        "sensor": {"duration_s": 10.0, "fps": 10.0, "old_key": 1},
        "object": {"seed": 1000},
        "mapping": {"pose": "track"},
        "viz": {"plots": False},
    }
    today = {"seed": 0, "sensor.duration_s": 20.0, "sensor.fps": 10.0, "object.seed": 0,
             "mapping.pose": "gt", "viz.plots": True}  # fmt: skip
    assert drift(recorded, {"mapping.pose": "track"}, today) == {"sensor.duration_s": (10.0, 20.0)}


def test_an_override_of_todays_value_is_redundant() -> None:
    today = {"sensor.duration_s": 20.0, "sensor.fingers": ["index", "thumb"]}
    overrides = {"sensor.duration_s": "20", "sensor.fingers": "[index,thumb]", "x": "1"}
    assert redundant(overrides, today) == {"sensor.duration_s", "sensor.fingers"}
    assert redundant({"sensor.duration_s": "30"}, today) == set()


def test_groups_are_the_overrides_that_are_not_leaves() -> None:
    recorded = {"sensor": {"duration_s": 20.0}, "seed": 1}
    overrides = {"object": "patchwork", "sensor.duration_s": "20", "seed": "1",
                 "launcher": "joblib", "hydra.job.chdir": "false", "perception": "oracle"}  # fmt: skip
    assert group_overrides(overrides, recorded) == ["object=patchwork", "perception=oracle"]


def test_show_writes_values_as_overrides_do() -> None:
    assert [show(v) for v in (10.0, True, None, ["a", 1])] == ["10.0", "true", "null", "[a,1]"]


def _recorded(object_name: str) -> dict:
    cfg = compose_config([f"object={object_name}"])
    return OmegaConf.to_container(cfg, resolve=False)


def _job(sweep: Path, name: str, overrides: list[str], config: dict, value: float) -> None:
    write_job(sweep, name, overrides, run_metrics(value, 90.0, 25.0, 33.0, "plastic"))
    (sweep / name / ".hydra" / "config.yaml").write_text(yaml.safe_dump(config))


def test_a_run_made_before_a_default_changed_is_shown_with_its_setting(tmp_path: Path) -> None:
    today = _recorded("patchwork")
    then = copy.deepcopy(today)
    then["sensor"]["duration_s"] = today["sensor"]["duration_s"] / 2
    sweep = tmp_path / "multirun" / "drift"
    _job(sweep, "0", ["object=patchwork", "seed=0"], then, 80.0)  # ran before the change
    same = f"sensor.duration_s={today['sensor']['duration_s']}"  # sets today's default
    _job(sweep, "1", ["object=patchwork", "seed=1", same], today, 90.0)
    page = generate(tmp_path, sweep)
    default_row = cells(section(page, "Multi-material objects"), "`patchwork`")
    assert default_row[2:4] == ["1", "90.0"]  # only the run at today's default
    other = section(page, "Other settings")
    assert f"sensor.duration_s={then['sensor']['duration_s']}" in other
    sources = section(page, "Sources")
    assert "defaults changed since these runs" in sources
    assert f"(today {today['sensor']['duration_s']})" in sources


def test_a_retired_group_option_reads_as_the_option_that_composes_it_today() -> None:
    # model=semantic_sdf_material_grid was semantic_sdf with the material grid that is now
    # semantic_sdf's default: such a run ran today's model, not another setting.
    assert current_overrides({"model": "semantic_sdf_material_grid", "seed": "1"}) == {"seed": "1"}
    assert current_overrides({"model": "semantic_sdf_no_concat"}) == {
        "model": "semantic_sdf_no_concat"
    }


def test_a_setting_added_since_reads_as_the_value_runs_before_it_had() -> None:
    recorded = {"classifier": {"max_patches": 8}, "mapping": {"pose": "gt"}}
    today = {"classifier.max_patches": 8, "classifier.patch_probe": 2, "mapping.pose": "gt"}
    assert drift(recorded, {}, today) == {"classifier.patch_probe": (0, 2)}
    assert drift({"classifier": {"max_patches": 8, "patch_probe": 2}}, {}, today) == {}
    # Without the key it came beside (another classifier, a partial record): skipped.
    assert drift({"classifier": {"_target_": "x"}}, {}, today) == {}
    # Steady presses came off (0) and became 3: a run from before reads as 0.
    mapper = {"label_vote_press_gap": 2}
    today = {"mapping.mapper.label_vote_press_gap": 2, "mapping.mapper.label_vote_steady_frames": 3}
    assert drift({"mapping": {"mapper": mapper}}, {}, today) == {
        "mapping.mapper.label_vote_steady_frames": (0, 3)
    }


def test_the_per_finger_cap_reads_as_the_camera_cap_runs_before_it_had() -> None:
    tracker = {"max_points_per_source": 1000, "source_weights": {"camera": 1.0, "tactile": 0.1}}
    today = {
        "mapping.tracker.max_points_per_source": 1000,
        "mapping.tracker.max_points_per_finger": 200,
        "mapping.tracker.source_weights.tactile": 0.5,
    }
    assert drift({"mapping": {"tracker": tracker}}, {}, today) == {
        "mapping.tracker.max_points_per_finger": (1000, 200),
        "mapping.tracker.source_weights.tactile": (0.1, 0.5),
    }


def test_tracker_settings_do_not_make_a_pose_gt_run_another_setting() -> None:
    """A run that read the simulator's pose never ran the tracker: today's tracker
    defaults cannot make it differ; a tracked run's can."""
    today = {"mapping.pose": "gt", "mapping.tracker.source_weights.tactile": 0.5}
    weights = {"tracker": {"source_weights": {"tactile": 0.0}}}
    assert drift({"mapping": {"pose": "gt", **weights}}, {}, today) == {}
    tracked = drift({"mapping": {"pose": "track", **weights}}, {"mapping.pose": "track"}, today)
    assert tracked == {"mapping.tracker.source_weights.tactile": (0.0, 0.5)}


def test_an_active_run_before_the_contact_share_reads_as_without_it() -> None:
    """Active runs from before weigh_by_contact ranked by score alone; a scripted run never
    asks the planner, so no planner setting makes it another setting."""
    today = {
        "sensor.policy": "scripted",
        "sensor.planner.candidates": 48,
        "sensor.planner.weigh_by_contact": True,
    }
    planner = {"candidates": 48}
    active = {"sensor": {"policy": "active", "planner": planner}}
    assert drift(active, {"sensor.policy": "active"}, today) == {
        "sensor.planner.weigh_by_contact": (False, True)
    }
    assert drift({"sensor": {"policy": "scripted", "planner": planner}}, {}, today) == {}


def test_an_active_run_before_chosen_turns_reads_as_turned_by_the_gait() -> None:
    """Runs from before sensor.planner.turn turned as the gait turns; the turn_* settings
    compare nothing there, and a run from before turn_offered_weight weighed offered places
    fully."""
    today = {
        "sensor.policy": "active",
        "sensor.planner.candidates": 48,
        "sensor.planner.turn": "advance",
        "sensor.planner.turn_gain": 1.25,
        "sensor.planner.turn_offered_weight": 0.3,
    }
    before = {"sensor": {"policy": "active", "planner": {"candidates": 48}}}
    assert drift(before, {}, today) == {"sensor.planner.turn": ("gait", "advance")}
    plain = {"candidates": 48, "turn": "gait", "turn_gain": 2.0, "turn_offered_weight": 1.0}
    assert drift({"sensor": {"policy": "active", "planner": plain}}, {}, today) == {
        "sensor.planner.turn": ("gait", "advance")
    }
    advice = {"candidates": 48, "turn": "advice", "turn_gain": 1.25}
    assert drift({"sensor": {"policy": "active", "planner": advice}}, {}, today) == {
        "sensor.planner.turn": ("advice", "advance"),
        "sensor.planner.turn_offered_weight": (1.0, 0.3),
    }


def test_the_acquisition_stages_make_no_offline_run_another_setting() -> None:
    """Offline the map is the same with one producer thread or two, the simulator in its own
    process or not; at realtime it is not."""
    today = {
        "sensor.pace": "offline",
        "mapping.acquire_thread": True,
        "mapping.acquire_process": True,
    }
    inline = {"mapping": {"acquire_thread": False, "acquire_process": False}}
    assert drift({"sensor": {"pace": "offline"}, **inline}, {}, today) == {}
    realtime = {"sensor": {"pace": "realtime"}, **inline}
    assert drift(realtime, {"sensor.pace": "realtime"}, today) == {
        "mapping.acquire_thread": (False, True),
        "mapping.acquire_process": (False, True),
    }


def test_runs_before_the_cpu_runtime_setting_read_as_run_in_torch() -> None:
    """The networks ran in torch until cpu_runtime came, with onnxruntime as its default."""
    today = {
        "classifier.cuda_graphs": True,
        "classifier.cpu_runtime": "onnxruntime",
        "mapping.mapper.tactile_depth.min_contact_px": 150,
        "mapping.mapper.tactile_depth.cpu_runtime": "onnxruntime",
    }
    before = {
        "classifier": {"cuda_graphs": True},
        "mapping": {"mapper": {"tactile_depth": {"min_contact_px": 150}}},
    }
    assert drift(before, {}, today) == {
        "classifier.cpu_runtime": ("torch", "onnxruntime"),
        "mapping.mapper.tactile_depth.cpu_runtime": ("torch", "onnxruntime"),
    }
    classifier_now = {"cuda_graphs": True, "cpu_runtime": "onnxruntime"}
    depth_now = {"min_contact_px": 150, "cpu_runtime": "onnxruntime"}
    now = {"classifier": classifier_now, "mapping": {"mapper": {"tactile_depth": depth_now}}}
    assert drift(now, {}, today) == {}


def test_runs_before_the_edge_min_confidence_setting_read_as_run_without_it() -> None:
    """Edge readings were never trusted alone until edge_min_confidence came (null, off);
    its default became 0.99 with the classifier adapted to the rig's edge imprints."""
    today = {"classifier.min_confidence": 0.8, "classifier.edge_min_confidence": 0.99}
    before = {"classifier": {"min_confidence": 0.8}}
    assert drift(before, {}, today) == {"classifier.edge_min_confidence": (None, 0.99)}
    now = {"classifier": {"min_confidence": 0.8, "edge_min_confidence": 0.99}}
    assert drift(now, {}, today) == {}


def test_a_run_from_before_the_fill_reads_as_the_branch_alone() -> None:
    mapper = {"material_weight": 0.1}
    today = {"mapping.mapper.material_weight": 0.1, "mapping.mapper.fill_m": 0.01}
    assert drift({"mapping": {"mapper": mapper}}, {}, today) == {
        "mapping.mapper.fill_m": (None, 0.01)
    }


@pytest.mark.parametrize(("pace", "then"), [("offline", None), ("realtime", 0.01)])
def test_a_pace_dependent_default_reads_as_the_value_it_had_in_the_run(pace: str, then) -> None:
    compose_config()  # registers the at_pace resolver, as the results page's composing does
    reach = "${at_pace:${oc.select:sensor.pace,offline},null,0.01}"
    recorded = {"sensor": {"pace": pace}, "mapping": {"mapper": {"label_vote_press_reach": reach}}}
    today = {"sensor.pace": pace, "mapping.mapper.label_vote_press_reach": 0.01}
    expected = {} if then == 0.01 else {"mapping.mapper.label_vote_press_reach": (then, 0.01)}
    assert drift(recorded, {}, today) == expected
    # both sides written as the same interpolation are compared as written
    assert drift(recorded, {}, {**today, "mapping.mapper.label_vote_press_reach": reach}) == {}
    # an interpolation that does not resolve stays as recorded
    lost = {"mapping": {"mapper": {"label_vote_press_reach": "${no_such_resolver:1}"}}}
    assert drift(lost, {}, today) == {
        "mapping.mapper.label_vote_press_reach": ("${no_such_resolver:1}", 0.01)
    }


def test_a_run_from_before_the_felt_ignored_faces_reads_as_the_generic_texture() -> None:
    today = {"sensor.tactile.texture_scale": 1.0, "sensor.tactile.ignored_faces": "nearest"}
    before = {"sensor": {"tactile": {"texture_scale": 1.0}}}
    assert drift(before, {}, today) == {"sensor.tactile.ignored_faces": ("generic", "nearest")}
    now = {"sensor": {"tactile": {"texture_scale": 1.0, "ignored_faces": "nearest"}}}
    assert drift(now, {}, today) == {}


def test_a_policy_sweeps_scripted_runs_at_the_defaults_join_the_object_table(
    tmp_path: Path,
) -> None:
    today = _recorded("patchwork")
    sweep = tmp_path / "multirun" / "policies"
    for k, policy in enumerate(("scripted", "active")):
        overrides = ["object=patchwork", "seed=0", f"sensor.policy={policy}"]
        _job(sweep, str(k), overrides, today, 90.0 + k)
    page = generate(tmp_path, sweep)
    # the scripted run is a default run: in the table beside its active-touch section
    assert cells(section(page, "Multi-material objects"), "`patchwork`")[2:4] == ["0", "90.0"]
    assert "sensor.policy=active" not in section(page, "Multi-material objects")
    assert cells(section(page, "Active touch"), "object=patchwork")[3] == "90.0"
