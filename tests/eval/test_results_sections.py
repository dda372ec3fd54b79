"""The pose-tracking and active-touch sections of the results page, on small fake sweeps."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.eval.test_results_page import cells, generate, run_metrics, section, table_rows
from tests.viz.test_sweep_plots import write_job


def curve(values: list[float]) -> list[list[float]]:
    """A mean-class curve scored every 5 frames at 10 Hz: [frame, time_s, value]."""
    return [[5 * k, 0.5 * k, v] for k, v in enumerate(values)]


@pytest.fixture
def default_sweep(tmp_path: Path) -> Path:
    """The `pose=gt` default-config runs the tracked and active runs are compared with."""
    sweep = tmp_path / "multirun" / "defaults"
    for seed, value in enumerate((96.0, 92.0)):
        metrics = run_metrics(value, 95.0, 50.0, 54.0, "plastic", fscore=0.98 + 0.01 * seed)
        metrics["oracles"] = ["object_pose"]
        metrics["matching_mean_class_curve"] = curve([50.0, 91.0, value])
        write_job(sweep, str(seed), ["object=patched_toy", f"seed={seed}"], metrics)
    return sweep


def tracked_metrics(value: float, error: float, seconds: float, load: float, **extra) -> dict:
    return run_metrics(
        value,
        95.0,
        50.0,
        54.0,
        "plastic",
        fscore=0.9,
        oracles=[],  # a tracked run drops the simulator's pose
        pose_error_mm=error,
        pose_error_max_mm=2 * error,
        pose_error_final_mm=error + 0.5,
        pose_frames_not_tracked=1,
        pose_frames_reinitialised=2,
        pose_frames_relocalised=1,
        pose_error_closest_mm=error / 2,
        pose_error_closest_final_mm=error / 4,
        pose_track_s_per_frame=seconds,
        load_avg=[load, 1.0, 1.0],
        **extra,
    )


def test_tracked_runs_get_the_pose_section_beside_the_pose_gt_runs(
    tmp_path: Path, default_sweep: Path
) -> None:
    sweep = tmp_path / "multirun" / "track"
    for seed, (value, error, seconds, load) in enumerate(
        ((90.0, 1.0, 2.0, 4.0), (80.0, 3.0, 1.0, 2.0))
    ):
        metrics = tracked_metrics(value, error, seconds, load)
        write_job(
            sweep, str(seed), ["object=patched_toy", f"seed={seed}", "mapping.pose=track"], metrics
        )
    write_job(  # no pose=gt run of this object: its reference cells say so
        sweep,
        "2",
        ["object=patchwork", "seed=0", "mapping.pose=track"],
        tracked_metrics(70.0, 9.0, 1.0, 3.0),
    )
    page = generate(tmp_path, default_sweep, sweep)
    pose = section(page, "Pose tracking")
    assert "Every run here: `mapping.pose=track`." in pose
    rows = {tuple(r[:2]): r[2:] for r in table_rows(pose)}
    assert rows[("object=patched_toy", "0")] == [
        "1.00 / 2.00 / 1.50",
        "0.50 / 0.25",
        "1 / 2 / 1",
        "2.00 (4)",
        "90.0",
        "50.0 (plastic)",
        "96.0",
        "0.900",
        "0.980",
    ]
    mean_row = rows[("object=patched_toy", "**mean**")]
    assert mean_row[:5] == ["2.00 / 4.00 / 2.50", "1.00 / 0.50", "2 / 4 / 2", "1.50 (3)", "85.0"]
    assert mean_row[6:] == ["94.0", "0.900", "0.985"]
    assert rows[("object=patchwork", "0")][6] == "n/a"
    # Tracked runs are reported here only: not as another setting, not in the object tables.
    assert "mapping.pose=track" not in section(page, "Other settings")
    assert [r[0] for r in table_rows(section(page, "Multi-material objects"))] == ["`patched_toy`"]


def test_a_pose_ablation_compares_within_its_own_sweep(tmp_path: Path, default_sweep: Path) -> None:
    sweep = tmp_path / "multirun" / "ablation_pose"
    for k, pose in enumerate(("gt", "track")):
        overrides = ["object=patched_toy", "seed=0", f"mapping.pose={pose}", "sensor.duration_s=3"]
        if pose == "gt":
            metrics = run_metrics(88.0, 95.0, 50.0, 54.0, "plastic", fscore=0.95)
            metrics["oracles"] = ["object_pose"]
        else:
            metrics = tracked_metrics(80.0, 2.0, 1.0, 2.0)
        write_job(sweep, str(k), overrides, metrics)
    page = generate(tmp_path, default_sweep, sweep)
    pose = section(page, "Pose tracking")
    assert "Every run here: `mapping.pose=track`, `sensor.duration_s=3`." in pose
    # The partner is the sweep's own pose=gt run (88.0), not the default run of seed 0 (96.0).
    row = cells(pose, "object=patched_toy")
    assert row[1] == "0" and row[8:] == ["88.0", "0.900", "0.950"]
    assert "No runs with other settings." in page


def test_policy_runs_pair_scripted_and_active_per_object_and_seed(
    tmp_path: Path, default_sweep: Path
) -> None:
    sweep = tmp_path / "multirun" / "policy"
    runs = {
        ("scripted", 0): (85.0, [40.0, 80.0, 85.0]),
        ("active", 0): (93.0, [40.0, 80.0, 93.0]),
        ("scripted", 1): (91.0, [40.0, 90.0, 91.0]),
        ("active", 1): (95.0, [40.0, 95.0, 95.0]),
    }
    for k, ((policy, seed), (value, values)) in enumerate(runs.items()):
        metrics = run_metrics(value, 95.0, 33.3, 40.0, "metal", oracles=["object_pose"])
        metrics["matching_mean_class_curve"] = curve(values)
        overrides = [
            "object=kitchen_tool",
            f"seed={seed}",
            f"sensor.policy={policy}",
            "viz.plots=False",
        ]
        write_job(sweep, str(k), overrides, metrics)
    plan = {"touch_plan": {"regrasps": [{"time_s": 3.0, "axis": [1, 0, 0]}]}}
    (sweep / "1" / "touch_suggestions.json").write_text(json.dumps(plan))  # active, seed 0
    page = generate(tmp_path, sweep)
    active = section(page, "Active touch")
    assert cells(active, "object=kitchen_tool")[1:] == [
        "0",
        "33.3 (metal)",
        "85.0",
        "-",  # never reached 90 %
        "75.0",  # touches labelled
        "93.0",
        "1.0 s",
        "75.0",
        "+8.0",
        "1",  # regrasps of the active run
    ]
    rows = {tuple(r[:2]): r[2:] for r in table_rows(active)}
    assert rows[("object=kitchen_tool", "1")][2:7] == ["0.5 s", "75.0", "95.0", "0.5 s", "75.0"]
    assert rows[("object=kitchen_tool", "**mean**")][1:] == [
        "88.0",
        "1 of 2 reached",
        "75.0",
        "94.0",
        "2 of 2 reached",
        "75.0",
        "+6.0",
        "1",  # seed 1's active run wrote no touch_suggestions.json: counted as unknown
    ]
    assert "Every run here" not in active  # viz.plots is bookkeeping, not a setting
    assert "No runs with other settings." in page


def active_only_section(tmp_path: Path, default_sweep: Path, extra: list[str]) -> str:
    """The active-touch section of a page whose one active run (patched_toy, seed 1,
    `extra` overrides) has no scripted partner in its own sweep."""
    sweep = tmp_path / "multirun" / "active_only"
    metrics = run_metrics(97.0, 95.0, 50.0, 54.0, "plastic", oracles=["object_pose"])
    metrics["matching_mean_class_curve"] = curve([40.0, 97.0, 97.0])
    overrides = ["object=patched_toy", "seed=1", "sensor.policy=active", *extra]
    write_job(sweep, "0", overrides, metrics)
    return section(generate(tmp_path, default_sweep, sweep), "Active touch")


def test_an_active_run_without_a_scripted_partner_takes_the_default_run(
    tmp_path: Path, default_sweep: Path
) -> None:
    active = active_only_section(tmp_path, default_sweep, [])
    assert "† no scripted run in this source" in active
    assert cells(active, "object=patched_toy")[3:] == [
        "92.0†",
        "0.5 s",
        "75.0",
        "97.0",
        "0.5 s",
        "75.0",
        "+5.0",
        "n/a",
    ]


def test_a_sweep_of_the_active_policy_alone_gets_its_own_means(
    tmp_path: Path, default_sweep: Path
) -> None:
    """No scripted run of its setting anywhere: the mean row gives the active runs' own
    figures instead of a row of n/a."""
    sweep = tmp_path / "multirun" / "active_16s"
    for seed, (value, values) in enumerate([(97.0, [40.0, 97.0, 97.0]), (89.0, [40, 80, 89])]):
        metrics = run_metrics(value, 95.0, 50.0, 54.0, "plastic", oracles=["object_pose"])
        metrics["matching_mean_class_curve"] = curve(values)
        overrides = ["object=patched_toy", f"seed={seed}", "sensor.policy=active"]
        write_job(sweep, str(seed), [*overrides, "sensor.duration_s=16"], metrics)
    active = section(generate(tmp_path, default_sweep, sweep), "Active touch")
    rows = {tuple(r[:2]): r[2:] for r in table_rows(active.split("active_16s", 1)[1])}
    assert rows[("object=patched_toy", "1")][1:3] == ["n/a", "n/a"]
    assert rows[("object=patched_toy", "**mean**")] == [
        "50.0 (plastic)", "n/a", "n/a", "n/a",
        "93.0", "1 of 2 reached", "75.0", "n/a", "n/a",
    ]  # fmt: skip


def test_an_active_run_of_a_setting_the_gait_never_reads_takes_the_default_run(
    tmp_path: Path, default_sweep: Path
) -> None:
    active = active_only_section(tmp_path, default_sweep, ["sensor.advice_lag_frames=3"])
    assert cells(active, "object=patched_toy")[3:5] == ["92.0†", "0.5 s"]


def test_without_tracked_or_policy_runs_the_sections_are_left_out(
    tmp_path: Path, default_sweep: Path
) -> None:
    page = generate(tmp_path, default_sweep)
    assert "## Pose tracking" not in page and "## Active touch" not in page
    sources = section(page, "Sources")
    assert "code version not recorded; finished 20" in sources  # when the results were written


def test_the_sources_name_the_commits_the_runs_ran(tmp_path: Path) -> None:
    sweep = tmp_path / "multirun" / "versions"
    for k, (commit, dirty) in enumerate((("a" * 40, False), ("a" * 40, True), (None, None))):
        metrics = run_metrics(80.0, 95.0, 50.0, 54.0, "plastic")
        metrics["code"] = {"commit": commit, "dirty": dirty}
        write_job(sweep, str(k), ["object=patched_toy", f"seed={k}"], metrics)
    sources = section(generate(tmp_path, sweep), "Sources")
    assert (
        "  - commit aaaaaaaaaa; 1 run with local changes; 1 run without a recorded version;"
        in sources
    )


def test_realtime_runs_show_what_the_pace_gave_up(tmp_path: Path) -> None:
    sweep = tmp_path / "multirun" / "pace"
    for k, (pace, frames, lag) in enumerate((("offline", 100, None), ("realtime", 2, 1.5))):
        metrics = run_metrics(80.0 if frames == 100 else 50.0, 95.0, 50.0, 54.0, "plastic")
        metrics.update(pace=pace, frames=frames, frames_dropped=100 - frames, lag_max_s=lag)
        metrics["perception"] = {"camera_mask": "segment", "camera_mask_iou": 0.5 + 0.4 * k}
        write_job(sweep, str(k), ["object=patched_toy", "seed=0", f"sensor.pace={pace}"], metrics)
    page = generate(tmp_path, sweep)
    other = section(page, "Other settings")
    # frames mapped, dropped, touches-only frames (n/a: not recorded then), largest lag
    realtime = ["2", "98", "n/a", "1.50"]
    assert cells(other, "object=patched_toy, sensor.pace=realtime")[-4:] == realtime
    assert cells(other, "object=patched_toy, sensor.pace=offline")[-4:] == [
        "100",
        "0",
        "n/a",
        "n/a",
    ]
    # The realtime run's few perceived frames stay out of the perception table.
    assert (
        cells(section(page, "Perception against the simulator's ground truth"), "`patched_toy`")[3]
        == "0.500 ± 0.000"
    )


def test_a_resumed_run_is_shown_beside_the_same_run_uninterrupted(tmp_path: Path) -> None:
    sweep = tmp_path / "multirun" / "resume"
    for name, value, segments in (
        ("whole", 87.62, [(0, 99)]),
        ("resumed", 87.56, [(0, 50), (51, 99)]),
    ):
        metrics = run_metrics(value, 97.5, 50.0, 96.3, "fabric", oracles=["object_pose"])
        metrics["segments"] = [{"first_frame": a, "last_frame": b} for a, b in segments]
        write_job(sweep, name, ["object=plushie", "seed=0", "viz.plots=false"], metrics)
    (sweep / "resumed" / "checkpoint.pt").write_bytes(b"0" * 2_500_000)
    page = generate(tmp_path, sweep)
    assert cells(section(page, "Resume"), "object=plushie")[1:] == [
        "0",
        "50",
        "87.62 / 87.56 (-0.06)",
        "97.50 / 97.50 (+0.00)",
        "50.0 / 96.3",
        "2.5",
    ]
    # The pair is not counted again among the default-config runs.
    assert "No default-config multi-material runs." in page


def test_shipped_checkpoints_come_from_their_reports(tmp_path: Path) -> None:
    from neuralfeels_sem.eval.results_assets import assets_section

    depth = tmp_path / "depth.json"
    held_out = {"overall": {"contact_iou": 0.95, "depth_mae_mm": 0.2}}
    held_out["per_finger"] = {"thumb": {"contact_iou": 0.9, "depth_mae_mm": 0.25}}
    depth.write_text(json.dumps({"held_out": held_out, "held_out_samples": 40, "train_wall_s": 60}))
    classifier = tmp_path / "classifier.json"
    report = {"test_accuracy": 0.975, "test_count": 80, "per_sensor": {"index": 0.95}}
    report["per_press_kind"] = {"edge": {"accuracy": 0.5, "count": 4}}
    classifier.write_text(json.dumps(report))
    text = "\n".join(assets_section(depth, classifier, ()))
    assert cells(text, "**overall**")[1:] == ["0.950", "0.200"]
    assert cells(text, "thumb")[1:] == ["0.900", "0.250"]
    assert cells(text, "**test split**")[1] == "97.5 (80)"
    assert cells(text, "sensor `index`")[1] == "95.0"
    assert cells(text, "press `edge`")[1] == "50.0 (4)"
    assert cells(text, "validation split")[1] == "n/a"  # absent from the report: not filled in
    assert "Trained on n/a presses over n/a backgrounds" in text
    assert "The gates" not in text and "Confusion" not in text  # no such blocks reported
    assert assets_section(tmp_path / "none.json", tmp_path / "none.json", ()) == []


def test_fresh_collections_show_presses_and_bend_radii(tmp_path: Path) -> None:
    from neuralfeels_sem.eval.results_assets import assets_section

    report = {"test_accuracy": 0.9, "test_count": 20, "data": {"root": "data/tactile/fresh"}}
    report["per_press_kind"] = {"feature": {"accuracy": 0.75, "count": 4}}
    report["per_curvature"] = {
        "R >= 80 mm": {"accuracy": 1.0, "count": 10},
        "R < 12 mm": {"accuracy": 0.5, "count": 6},
    }
    report["gated"] = {"kept_share": 0.8, "accuracy_kept": 0.95}
    (tmp_path / "held_out_1.json").write_text(json.dumps(report))
    none = tmp_path / "none.json"
    text = "\n".join(assets_section(none, none, [tmp_path / "held_out_1.json", none]))
    assert "## Shipped checkpoints" in text and "(`data/tactile/fresh`)" in text
    assert cells(text, "**all images**")[1] == "90.0 (20)"
    assert cells(text, "press `feature`")[1] == "75.0 (4)"
    assert cells(text, "bend radius `R < 12 mm`")[1] == "50.0 (6)"
    assert text.index("`R < 12 mm`") < text.index("`R >= 80 mm`")  # tightest bend first
    assert cells(text, "accuracy on the kept touches")[1] == "95.0"


def test_shipped_classifier_training_gates_and_confusion_come_from_its_files(
    tmp_path: Path,
) -> None:
    from neuralfeels_sem.eval.results_assets import assets_section

    report = {"test_accuracy": 0.75, "test_count": 8, "class_names": ["metal", "wood"]}
    report["confusion"] = [[3, 1], [1, 3]]
    report["data"] = {"images": 40}
    report["counts"] = {"train": 24, "val": 8, "test": 8}
    report["training"] = {"epochs_run": 5, "best_epoch": 4, "lr": 0.001}
    report["training"] |= {"lr_schedule": "cosine", "batch_size": 4}
    report["gated_test"] = {"min_confidence": 0.8, "max_edge_share": 0.5, "kept_count": 6}
    report["gated_test"] |= {"left_out_low_confidence": 1, "left_out_edge": 1}
    (tmp_path / "report.json").write_text(json.dumps(report))
    manifest = {"dataset": {"press_counts": {"centre": 30, "edge": 10}}}
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    depth = {"train_samples": 20, "train_backgrounds": ["procedural:0", "real.png"]}
    depth |= {"settings": {"epochs": 3, "batch_size": 2}, "train_wall_s": 9.6}
    (tmp_path / "depth.json").write_text(json.dumps(depth))
    text = "\n".join(assets_section(tmp_path / "depth.json", tmp_path / "report.json", ()))
    assert (
        "Trained on 20 presses over 2 backgrounds, 3 epochs at batch 2; training took 10 s" in text
    )
    assert "40 simulated images (presses: centre 30, edge 10), split 24 / 8 / 8" in text
    assert "5 epochs, lr 0.001 (cosine), batch 4; kept epoch 4" in text
    assert "kept 6 of 8 test images; they left out 1 for low confidence and 1 for" in text
    assert cells(text, "`metal`")[1:] == ["3", "1"]
    assert cells(text, "`wood`")[1:] == ["1", "3"]
    # Without a manifest beside the report the kinds of press are left out.
    (tmp_path / "manifest.json").unlink()
    text = "\n".join(assets_section(tmp_path / "depth.json", tmp_path / "report.json", ()))
    assert "40 simulated images, split 24 / 8 / 8 (train / validation / test). Last" in text
    # A round that mixed another collection's presses into every epoch says so.
    report["training"]["mix"] = {"sim_per_epoch": 24, "sim_images": 100}
    (tmp_path / "report.json").write_text(json.dumps(report))
    text = "\n".join(assets_section(tmp_path / "depth.json", tmp_path / "report.json", ()))
    assert "(train / validation / test); each epoch mixed with 24 draws from 100 simulated" in text


def test_uncertainty_rows_per_source_and_object(tmp_path: Path, default_sweep: Path) -> None:
    for k, auroc in enumerate((0.9, 0.7)):
        path = default_sweep / str(k) / "metrics.json"
        metrics = json.loads(path.read_text())
        metrics["uncertainty"] = {
            "auroc": auroc,
            "ece": 0.05,
            "error_share": 0.1 * (k + 1),
            "mean_entropy_correct": 0.1,
            "mean_entropy_wrong": 0.4,
        }
        path.write_text(json.dumps(metrics))
    page = generate(tmp_path, default_sweep)
    row = cells(section(page, "Uncertainty of the material map"), f"`{default_sweep}`")
    assert row[1:] == [
        "`patched_toy`",
        "2",
        "94.0 ± 2.8",
        "50.0 (plastic)",
        "15.0 ± 7.1",
        "0.80 ± 0.14",
        "0.050 ± 0.000",
        "0.10 ± 0.00 / 0.40 ± 0.00",
    ]


def test_a_tracker_setting_keeps_the_pose_gt_reference(tmp_path: Path, default_sweep: Path) -> None:
    """A `pose=gt` run never reads the tracker's settings: a tracked run with its own
    still compares with the default run of the object and seed."""
    sweep = tmp_path / "multirun" / "camera_only"
    overrides = [
        "object=patched_toy",
        "seed=0",
        "mapping.pose=track",
        "mapping.tracker.source_weights.tactile=0",
    ]
    write_job(sweep, "0", overrides, tracked_metrics(90.0, 1.0, 2.0, 4.0))
    pose = section(generate(tmp_path, default_sweep, sweep), "Pose tracking")
    row = next(r for r in table_rows(pose) if r[1] == "0")
    assert row[8] == "96.0"  # the default sweep's pose=gt run of patched_toy, seed 0


def test_realtime_runs_count_the_frames_whose_touches_alone_were_fused(tmp_path: Path) -> None:
    """Frames mapped and dropped, the frames whose touches alone were fused (n/a for a run
    from before that count existed) and the largest lag, as ranges over the seeds."""
    sweep = tmp_path / "multirun" / "touches"
    for seed, touches in ((0, 40), (1, 55), (2, None)):
        pace = {"pace": "realtime", "frames": 50 + seed, "frames_dropped": 250 - seed}
        pace |= {"lag_max_s": 1.0 + seed / 10} | (
            {} if touches is None else {"touch_frames": touches}
        )
        metrics = run_metrics(90.0, 95.0, 50.0, 54.0, "plastic", **pace)
        overrides = ["object=patched_toy", "sensor.pace=realtime", f"seed={seed}"]
        write_job(sweep, str(seed), overrides, metrics)
    other = section(generate(tmp_path, sweep), "Other settings")
    header = next(line for line in other.splitlines() if line.startswith("| setting"))
    assert header.endswith("| frames mapped | frames dropped | touch frames | lag max s |")
    assert cells(other, "object=patched_toy")[-4:] == ["50-52", "248-250", "40-55", "1.00-1.20"]
