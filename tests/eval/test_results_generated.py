"""The results page's section for runs on generated objects (object=random)."""

from __future__ import annotations

from pathlib import Path

from tests.eval.test_results_page import cells, generate, run_metrics, section
from tests.viz.test_sweep_plots import write_job


def generated_metrics(seed: int, mean_class: float, auroc: float, family: str = "boxy") -> dict:
    made = {"seed": seed, "family": family, "size_m": 0.09, "materials": ["metal", "wood"],
            "regions": ["band"]}  # fmt: skip
    return run_metrics(
        mean_class, 90.0, 50.0, 60.0, "wood",
        accuracy=0.95, coverage=0.6, oracles=["object_pose"],
        uncertainty={"auroc": auroc}, config={"object": f"random_{seed}", "object_generation": made},
    )  # fmt: skip


def write_generated(sweep: Path, values: dict[int, float], extra: list[str], start: int = 0) -> int:
    k = start
    for seed, value in values.items():
        overrides = ["object=random", f"object.seed={seed}", "seed=0", *extra]
        write_job(sweep, str(k), overrides, generated_metrics(seed, value, 0.8))
        k += 1
    return k


def test_generated_objects_get_a_row_each_a_mean_and_the_share_at_the_target(
    tmp_path: Path,
) -> None:
    sweep = tmp_path / "multirun" / "unseen"
    write_generated(sweep, {1000: 90.0, 1001: 70.0, 1002: 86.0}, [])
    page = generate(tmp_path, sweep)
    part = section(page, "Generated objects")
    assert "evaluation objects. Mean-class matching at or above 80 %: 2 of 3 objects" in part
    assert "lowest 70.0 (seed 1001)" in part
    row = cells(part, "1001")
    assert row[1:] == [
        "boxy, 9 cm", "2: band", "1", "70.0", "50.0 (wood)", "95.0", "60.0", "0.80", "-",
    ]  # fmt: skip
    assert cells(part, "**mean**")[4] == "**82.0 ± 10.6**"
    # Their own section only: not a settings table, not the uncertainty table.
    assert "object.seed" not in section(page, "Other settings")


def test_a_material_a_run_never_read_rightly_is_named_with_why_and_its_seed(
    tmp_path: Path,
) -> None:
    sweep = tmp_path / "multirun" / "unseen"
    wood_read = {"touches": 5, "judged": 4, "correct": 4}
    for seed, wood in enumerate([wood_read, None]):
        metrics = generated_metrics(1003, 90.0 if wood else 50.0, 0.8)
        metrics["matching_per_class"] = {"metal": 99.0, "wood": 80.0 if wood else 0.0}
        by_material = {"metal": {"touches": 9, "judged": 9, "correct": 9}}
        by_material.update({"wood": wood} if wood else {})
        metrics["classifier_accuracy"].update(by_material=by_material, judged=13, abstentions=1)
        overrides = ["object=random", "object.seed=1003", f"seed={seed}"]
        write_job(sweep, str(seed), overrides, metrics)
    part = section(generate(tmp_path, sweep), "Generated objects")
    assert cells(part, "1003")[4] == "70.0 (90.0, 50.0)"
    assert cells(part, "1003")[-1] == "wood: never pressed (seed 1, map 0.0 %)"
    assert cells(part, "**mean**")[-1] == "1 of 2 runs"


def test_settings_on_the_same_objects_are_compared_on_the_objects_both_ran(
    tmp_path: Path,
) -> None:
    sweep = tmp_path / "multirun" / "dev"
    k = write_generated(sweep, {1: 80.0, 2: 60.0, 3: 99.0}, [])
    write_generated(sweep, {1: 90.0, 2: 70.0}, ["mapping.mapper.label_vote_radius=0.01"], k)
    part = section(generate(tmp_path, sweep), "Generated objects")
    assert "Pooled on object seeds 1, 2 (every setting ran them)." in part
    assert cells(part, "today's defaults (oracles: pose)")[1:6] == [
        "80.0, 60.0", "**70.0 ± 14.1**", "50.0", "1 of 2", "60.0 (seed 2)",
    ]  # fmt: skip
    other = "`mapping.mapper.label_vote_radius=0.01` (oracles: pose)"
    assert cells(part, other)[1:6] == [
        "90.0, 70.0",
        "**80.0 ± 14.1**",
        "50.0",
        "1 of 2",
        "70.0 (seed 2)",
    ]
    assert "development objects" in part


def test_development_objects_of_several_sweeps_are_compared_together(tmp_path: Path) -> None:
    first, second = tmp_path / "multirun" / "dev_a", tmp_path / "multirun" / "dev_b"
    write_generated(first, {1: 80.0, 2: 60.0}, [])
    write_generated(second, {1: 90.0, 2: 70.0, 3: 75.0}, ["mapping.mapper.steps_policy=surprise"])
    write_generated(second, {1000: 85.0}, ["mapping.mapper.steps_policy=surprise"], 3)
    part = section(generate(tmp_path, first, second), "Generated objects")
    assert part.count("### Development objects, every source") == 1
    assert "Pooled on object seeds 1, 2 (every setting ran them)." in part
    assert cells(part, "today's defaults (oracles: pose)")[1:3] == ["80.0, 60.0", "**70.0 ± 14.1**"]
    surprise = "`mapping.mapper.steps_policy=surprise` (oracles: pose)"
    assert cells(part, surprise)[1:3] == ["90.0, 70.0", "**80.0 ± 14.1**"]
    # Objects listed for today's defaults only; the evaluation object keeps its sweep's table.
    assert "Setting: today's defaults (oracles: pose); development objects." in part
    assert f"Setting: {surprise}; development objects." not in part
    assert "multirun/dev_b`" in part and "evaluation objects. Mean-class" in part


def test_settings_on_other_objects_are_each_compared_with_the_defaults(tmp_path: Path) -> None:
    """Two settings with no object in common: each gets a comparison with today's defaults
    on the objects it shares with them, not one comparison over nothing."""
    sweep = tmp_path / "multirun" / "dev"
    k = write_generated(sweep, {1: 80.0, 2: 60.0, 3: 99.0, 4: 70.0}, [])
    k = write_generated(sweep, {1: 90.0, 2: 70.0, 3: 95.0}, ["sensor.policy=active"], k)
    write_generated(sweep, {4: 75.0}, ["mapping.mapper.label_vote_radius=0.02"], k)
    part = section(generate(tmp_path, sweep), "Generated objects")
    assert "n/a" not in part
    first = part.index("Pooled on object seeds 1, 2, 3 (every setting ran them).")
    second = part.index("Pooled on object seeds 4 (every setting ran them).")
    assert first < second  # the larger set first
    defaults = [c for c in part.splitlines() if c.startswith("| today's defaults")]
    assert [row.split(" | ")[1] for row in defaults] == ["80.0, 60.0, 99.0", "70.0"]


def test_tracked_runs_on_generated_objects_go_to_the_pose_section(tmp_path: Path) -> None:
    """Beside the `pose=gt` run of the same object from another sweep; they are not a
    setting of the development comparison (which would shrink it to the objects they ran)."""
    reference, tracked = tmp_path / "multirun" / "dev", tmp_path / "multirun" / "dev_track"
    write_generated(reference, {1: 80.0, 2: 60.0, 3: 70.0}, [])
    for k, seed in enumerate((1, 2)):
        metrics = generated_metrics(seed, 75.0 + k, 0.8)
        metrics.update(oracles=[], pose_error_mm=1.0 + k, pose_error_max_mm=2.0,
                       pose_error_final_mm=1.5, pose_frames_not_tracked=0)  # fmt: skip
        overrides = ["object=random", f"object.seed={seed}", "seed=0", "mapping.pose=track"]
        write_job(tracked, str(k), overrides, metrics)
    page = generate(tmp_path, reference, tracked)
    part = section(page, "Generated objects")
    assert "Pooled on" not in part and "mapping.pose" not in part  # one setting only
    pose = section(page, "Pose tracking")
    row = cells(pose, "object=random, object.seed=2")
    assert row[2] == "2.00 / 2.00 / 1.50" and row[6] == "76.0" and row[8] == "60.0"


def test_active_runs_on_generated_objects_beside_their_scripted_runs(tmp_path: Path) -> None:
    """An active-touch sweep on generated objects is compared with the scripted (default)
    run of the same object from another sweep."""
    reference, active = tmp_path / "multirun" / "dev", tmp_path / "multirun" / "dev_active"
    write_generated(reference, {1: 80.0, 2: 60.0}, [])
    write_generated(active, {2: 70.0}, ["sensor.policy=active"])
    page = generate(tmp_path, reference, active)
    row = cells(section(page, "Active touch"), "object=random")  # object.seed=2: every run
    assert row[3] == "60.0†" and row[6] == "70.0" and row[9] == "+10.0"


def test_a_preset_picked_generated_object_is_the_same_object(tmp_path: Path) -> None:
    """A sweep that picked object=random through a preset names its runs by the metrics'
    `random_<seed>`; a tracked run with `object=random` finds it as its pose=gt partner."""
    reference, tracked = tmp_path / "multirun" / "eval", tmp_path / "multirun" / "eval_track"
    write_job(
        reference,
        "0",
        ["object.seed=1000", "seed=0", "experiment=unseen_objects"],
        generated_metrics(1000, 90.0, 0.8),
    )
    metrics = generated_metrics(1000, 80.0, 0.8)
    metrics.update(oracles=[], pose_error_mm=1.0, pose_error_max_mm=2.0, pose_error_final_mm=1.5)
    overrides = ["object=random", "object.seed=1000", "seed=0", "mapping.pose=track"]
    write_job(tracked, "0", overrides, metrics)
    pose = section(generate(tmp_path, reference, tracked), "Pose tracking")
    assert cells(pose, "object=random")[8] == "90.0"


def test_evaluation_sweeps_of_one_setting_are_pooled_with_each_run_shown(tmp_path: Path) -> None:
    """experiment=unseen_objects at mapping seeds 0 and 1 (two sweeps): one table, each
    object's mean with its runs beside it, and how many runs reach the target; a sweep of
    another setting on the same objects keeps a table of its own."""
    first, second = tmp_path / "multirun" / "eval_s0", tmp_path / "multirun" / "eval_s1"
    other = tmp_path / "multirun" / "eval_active"
    write_generated(first, {1000: 98.0, 1001: 90.0}, [])
    write_generated(second, {1000: 50.0, 1001: 92.0}, [])
    write_generated(other, {1000: 85.0, 1001: 80.0}, ["sensor.policy=active"])
    part = section(generate(tmp_path, first, second, other), "Generated objects")
    assert "multirun/eval_s0`, `" in part and part.count("multirun/eval_s1`") == 1
    assert cells(part, "1000")[3:5] == ["2", "74.0 (98.0, 50.0)"]
    assert (
        "at or above 80 %: 1 of 2 objects; lowest 74.0 (seed 1000). Runs at or above: 3 of 4."
        in part
    )
    assert "multirun/eval_active`" in part and "its settings compared" not in part


def test_an_evaluation_sweep_of_two_settings_compares_them(tmp_path: Path) -> None:
    sweep = tmp_path / "multirun" / "eval_policies"
    k = write_generated(sweep, {1000: 90.0, 1001: 70.0}, [])
    write_generated(sweep, {1000: 95.0, 1001: 85.0}, ["sensor.policy=active"], k)
    part = section(generate(tmp_path, sweep), "Generated objects")
    assert "multirun/eval_policies`: its settings compared" in part
    assert cells(part, "`sensor.policy=active` (oracles: pose)")[1:3] == [
        "95.0, 85.0",
        "**90.0 ± 7.1**",
    ]


def test_the_readme_states_the_evaluation_set_at_todays_defaults(tmp_path: Path) -> None:
    """Beside its table the front page gets one generated sentence on the evaluation
    objects: today's default-config runs of every sweep pooled, other settings left out."""
    from neuralfeels_sem.eval.results_page import README_BEGIN, README_END
    from neuralfeels_sem.tasks.results_page import main
    from tests.eval.test_results_page import write_object_sweep

    shipped = write_object_sweep(tmp_path / "multirun" / "shipped")
    first, second = tmp_path / "multirun" / "eval_s0", tmp_path / "multirun" / "eval_s1"
    write_generated(first, {1000: 98.0, 1001: 90.0}, [])
    write_generated(second, {1000: 50.0, 1001: 92.0}, ["seed=1"])
    write_generated(tmp_path / "multirun" / "active", {1000: 10.0}, ["sensor.policy=active"])
    readme = tmp_path / "README.md"
    readme.write_text(f"# Front\n{README_BEGIN}\n| old |\n{README_END}\n")
    dirs = [str(d) for d in (shipped, first, second, tmp_path / "multirun" / "active")]
    assert main(["--out", str(tmp_path / "results.md"), "--readme", str(readme), *dirs]) == 0
    block = readme.read_text().split(README_BEGIN)[1].split(README_END)[0].strip()
    sentence = block.split("\n\n")[-1]
    assert sentence.startswith("**Objects nobody tuned on**: the 2 generated evaluation objects")
    assert "4 runs, mapping seeds 0, 1; oracles: pose" in sentence
    # objects 1000 (74.0) and 1001 (91.0): mean 82.5; majority map 50.0
    assert "**82.5 %** mean-class on average against 50.0 % for the majority map" in sentence
    assert "3 of 4 runs at or above 80 %, the lowest object 74.0 % (seed 1000)." in sentence
    assert "runs below" not in sentence  # no touches to judge in these runs: nothing said
    assert sentence.rstrip().endswith(".*") and "*Runs: " in sentence


def test_the_summary_says_which_runs_below_the_target_lost_a_material_and_why() -> None:
    from neuralfeels_sem.eval.results_generated import lost_materials_text
    from neuralfeels_sem.eval.results_runs import Run

    def run(mean_class: float, wood_recall: float, wood: dict | None) -> Run:
        by_material = {"metal": {"touches": 9, "judged": 9, "correct": 9}}
        by_material.update({"wood": wood} if wood else {})
        metrics = {
            "matching_mean_class_pct": mean_class,
            "matching_per_class": {"metal": 99.0, "wood": wood_recall},
            "classifier_accuracy": {"by_material": by_material, "judged": 9, "abstentions": 1},
        }
        return Run(path=Path("run"), overrides={}, metrics=metrics, config={})

    abstained = {"touches": 2, "judged": 0, "correct": 0}
    runs = [
        run(50.0, 0.0, None),  # lost, never pressed
        run(55.0, 10.0, abstained),  # lost, never labelled
        run(75.0, 60.0, abstained),  # below the target, but wood mapped from patch readings
        run(95.0, 90.0, None),  # at the target: not counted
    ]
    text = lost_materials_text(runs)
    assert text == (
        " Of the 3 runs below 80 %, 2 lost a material no touch read rightly"
        " (1 never pressed, 1 never labelled)."
    )
    assert lost_materials_text(runs[3:]) == ""
