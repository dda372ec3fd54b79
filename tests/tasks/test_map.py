"""task=map end to end on the simulated rig, at toy size: every run output, resume, task=eval."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh

from tests.helpers import run_cli

TINY = [
    "object=plushie",
    "classifier=oracle",
    "sensor.duration_s=1.6",
    "sensor.fps=5",
    "sensor.rgbd.width=160",
    "sensor.rgbd.height=120",
    "mapping.mapper.warmup_steps=20",
    "mapping.mapper.steps_per_frame=3",
    "mapping.checkpoint_every=4",
    "eval.every_k_frames=2",
    "eval.num_surface_samples=2000",
    "eval.image_views=2",
    "eval.image_size=64",
    "eval.mesh_resolution=48",
    "eval.shape_samples=2000",
    "viz.progression_snapshots=2",
]
OUTPUTS = (
    "metrics.json",
    "material_mesh.ply",
    "matching_curve.png",
    "material_maps.png",
    "uncertainty_map.png",
    "progression.png",
    "checkpoint.pt",
    "touches.csv",
    "segmentation.png",
    "segmentation_worst.png",
    ".hydra/config.yaml",
)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    run_dir = tmp_path_factory.mktemp("map") / "run"
    result = run_cli([*TINY, f"hydra.run.dir={run_dir}"], timeout=900)
    assert result.returncode == 0, result.stderr[-4000:]
    assert f"run directory: {run_dir}" in result.stdout
    header = next(line for line in result.stdout.splitlines() if line.startswith("metric"))
    assert header.split() == ["metric", "run", "majority", "untrained"]
    assert "mean-class matching" in result.stdout
    assert "uncertainty AUROC / ECE" in result.stdout
    return run_dir


def test_map_writes_the_run_output_contract(tiny_run: Path) -> None:
    for name in OUTPUTS:
        assert (tiny_run / name).is_file(), name
    metrics = json.loads((tiny_run / "metrics.json").read_text())
    for key in (
        "matching_pct",
        "matching_curve",
        "fscore_5mm",
        "chamfer_mm",
        "classifier_accuracy",
        "frames",
        "wall_s",
        "realtime_factor",
        "config",
        "baseline",
        "trained_on",
        "matching_mean_class_pct",
        "matching_miou_pct",
        "matching_mesh_pct",
        "matching_mean_class_curve",
        "baseline_majority",
        "margin_over_majority",
    ):
        assert key in metrics, key
    assert metrics["frames"] == 8
    assert metrics["config"]["object"] == "plushie" and metrics["config"]["seed"] == 0
    assert metrics["config"]["object_generation"] is None  # set for object=random only
    assert [row[0] for row in metrics["matching_curve"]] == [0, 2, 4, 6, 7]
    trained = metrics["trained_on"]
    assert trained["camera_points"] > 0 and trained["tactile_points"] > 0
    assert trained["labelled_touches"] > 0 and trained["optimizer_steps"] == 20 + 7 * 3
    # Measured, not estimated: sensor time over wall time.
    assert metrics["realtime_factor"] == pytest.approx(metrics["sensor_time_s"] / metrics["wall_s"])
    assert metrics["sensor_time_s"] == pytest.approx(1.6)
    # A timing is only worth quoting with the machine and its load.
    assert metrics["machine"]["cpus"] >= 1 and metrics["machine"]["torch_threads"] >= 1
    assert metrics["machine"]["device"] == "cpu" and len(metrics["load_avg"]) == 3
    commit = metrics["code"]["commit"]  # null only outside a git checkout
    assert commit is None or (len(commit) == 40 and isinstance(metrics["code"]["dirty"], bool))
    # A toy run (8 frames) learns the shape and the materials its touches read: its map
    # scores at least the majority map in mean-class matching, and its shape beats the
    # untrained field's. (What the untrained field paints is down to its initial weights: it
    # may already be the majority material, so it is no floor to beat in matching. Plain
    # matching is no floor either: after 8 frames the fill gives a press of plushie's small
    # plastic patches the whole region up to the fabric presses, and plain matching weighs
    # that against 96 % fabric.)
    majority = metrics["baseline_majority"]
    assert metrics["matching_mean_class_pct"] > majority["matching_mean_class_pct"]
    assert metrics["fscore_5mm"] > metrics["baseline"]["fscore_5mm"]
    assert metrics["classifier_accuracy"]["overall"] == pytest.approx(1.0)  # the oracle


def test_map_scores_its_uncertainty_against_its_errors(tiny_run: Path) -> None:
    metrics = json.loads((tiny_run / "metrics.json").read_text())
    block = metrics["uncertainty"]
    assert block["samples"] == 2000
    assert block["error_share"] == pytest.approx(1.0 - metrics["matching_pct"] / 100.0, abs=1e-3)
    assert 0.0 <= block["ece"] <= 1.0 and 0.0 <= block["mean_entropy"] <= 1.0
    if block["auroc"] is None:  # a map with no wrong sample
        assert "undefined" in block["note"]
    else:
        assert 0.0 <= block["auroc"] <= 1.0
        assert block["mean_entropy_wrong"] is not None
    ply = trimesh.load(tiny_run / "material_mesh.ply", process=False)
    uncertainty = ply.metadata["_ply_raw"]["vertex"]["data"]["uncertainty"]
    assert len(uncertainty) == len(ply.vertices)
    assert uncertainty.min() >= 0.0 and uncertainty.max() <= 1.0


def test_map_reads_every_figure_against_the_majority_map(tiny_run: Path) -> None:
    metrics = json.loads((tiny_run / "metrics.json").read_text())
    majority = metrics["baseline_majority"]
    classes = len(metrics["matching_per_class"])
    assert majority["material"] == "fabric" and classes == 2  # the plushie: fabric, plastic
    # A constant map is right on one class and wrong on the others.
    assert majority["matching_mean_class_pct"] == pytest.approx(100.0 / classes)
    assert majority["matching_pct"] > 90.0  # and yet scores the fabric share
    assert metrics["matching_mean_class_pct"] == pytest.approx(
        sum(metrics["matching_per_class"].values()) / classes
    )
    assert metrics["margin_over_majority"]["matching_mean_class_pct"] == pytest.approx(
        metrics["matching_mean_class_pct"] - majority["matching_mean_class_pct"]
    )
    frames = [row[:2] for row in metrics["matching_curve"]]
    assert [row[:2] for row in metrics["matching_mean_class_curve"]] == frames
    assert metrics["matching_mean_class_curve"][-1][2] == pytest.approx(
        metrics["matching_mean_class_pct"]
    )
    # The toy run perceives as a real rig would, apart from the pose and its oracle classifier.
    assert metrics["oracles"] == ["object_pose", "material_labels"]
    perception = metrics["perception"]
    assert perception["camera_mask"] == "segment" and perception["tactile_depth_source"] == "net"
    assert perception["camera_frames_segmented"] == metrics["frames"]
    assert perception["camera_mask_iou"] > 0.8  # scored against the simulator's mask
    assert perception["tactile_readings_scored"] > 0
    assert 0 <= perception["tactile_readings_unchanged"] <= perception["tactile_readings_scored"]
    assert 0.0 <= perception["tactile_depth_mae_mm"] < 1.0
    assert 0.0 <= metrics["matching_mesh_pct"] <= 100.0
    assert 0.0 <= metrics["matching_miou_pct"] <= 100.0
    acc = metrics["classifier_accuracy"]
    assert acc["coverage"] == pytest.approx(acc["judged"] / (acc["judged"] + acc["abstentions"]))
    assert acc["accuracy_all_touches"] == pytest.approx(acc["overall"] * acc["coverage"])


def test_task_eval_rescores_a_finished_run(tiny_run: Path) -> None:
    result = run_cli(
        [
            "task=eval",
            f"run_dir={tiny_run}",
            "eval.image_size=64",
            "eval.image_views=2",
            "eval.mesh_resolution=48",
            "eval.num_surface_samples=2000",
            "eval.shape_samples=2000",
        ]
    )
    assert result.returncode == 0, result.stderr[-3000:]
    original = json.loads((tiny_run / "metrics.json").read_text())
    again = json.loads((tiny_run / "eval" / "metrics.json").read_text())
    # A compact checkpoint holds the table in float16 (mapping/checkpoint_codec.py): the
    # field moves by its rounding, so a sample or two of 2000 may change sides (0.05 points
    # of matching each; a shape sample crossing 5 mm moves the F-score by about 3e-4).
    for key in (
        "matching_pct",
        "matching_mean_class_pct",
        "matching_miou_pct",
        "matching_mesh_pct",
    ):
        assert again[key] == pytest.approx(original[key], abs=0.2), key
    assert again["baseline_majority"] == original["baseline_majority"]
    assert again["fscore_5mm"] == pytest.approx(original["fscore_5mm"], abs=2e-3)
    assert (tiny_run / "eval" / "material_maps.png").is_file()


def test_task_eval_refuses_a_directory_that_is_not_a_run(tmp_path: Path) -> None:
    result = run_cli(["task=eval", f"run_dir={tmp_path}"])
    assert result.returncode == 2
    assert "is not a mapping run" in result.stderr
    assert "Traceback" not in result.stderr


def test_task_eval_names_overrides_that_no_longer_compose(tmp_path: Path) -> None:
    from hydra import initialize_config_dir

    from neuralfeels_sem.core.errors import ConfigError
    from neuralfeels_sem.tasks.eval import load_run_config
    from tests.helpers import CONF_DIR, register_configs

    register_configs()
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "config.yaml").write_text("task:\n  name: map\n")
    (tmp_path / ".hydra" / "overrides.yaml").write_text("- mapping.mapper.interior_samples=4\n")
    (tmp_path / "checkpoint.pt").write_bytes(b"")
    with (
        initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"),
        pytest.raises(ConfigError, match="no longer compose") as info,
    ):
        load_run_config(tmp_path)
    assert "\n" not in str(info.value) and "interior_samples" in str(info.value)


def test_resume_continues_from_the_checkpoint(tiny_run: Path, tmp_path: Path) -> None:
    result = run_cli(
        [
            *TINY,
            f"mapping.resume={tiny_run / 'checkpoint.pt'}",
            "sensor.duration_s=2.4",
            "viz.plots=false",  # the pictures are the first run's test
            f"hydra.run.dir={tmp_path}",
        ],
        timeout=900,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    # Frames 0-7 came from the checkpoint (its segment), 8-11 from this one: the metrics
    # cover both, and the earlier snapshots were copied into this directory.
    assert metrics["frames"] == 12 and metrics["partial"] is False
    assert [(s["first_frame"], s["last_frame"]) for s in metrics["segments"]] == [(0, 7), (8, 11)]
    assert metrics["wall_s"] == pytest.approx(sum(s["wall_s"] for s in metrics["segments"]))
    assert {p.name for p in (tiny_run / "progression").glob("*.npz")} <= {
        p.name for p in (tmp_path / "progression").glob("*.npz")
    }
    assert metrics["trained_on"]["frames"] == 12
    # The perception figures cover both segments too (restored from the checkpoint).
    assert metrics["perception"]["camera_frames_segmented"] == 12
    assert metrics["matching_curve"][0][0] == 0 and metrics["matching_curve"][-1][0] == 11
    assert [r[0] for r in metrics["matching_mean_class_curve"]] == [
        r[0] for r in metrics["matching_curve"]
    ]


def test_resume_with_another_model_variant_is_refused(tiny_run: Path, tmp_path: Path) -> None:
    result = run_cli(
        [
            *TINY,
            f"mapping.resume={tiny_run / 'checkpoint.pt'}",
            "model.sdf.hidden_dim=32",
            f"hydra.run.dir={tmp_path}",
        ]
    )
    assert result.returncode == 2
    assert "different model" in result.stderr


def test_a_tracked_pose_at_realtime_on_a_cpu_is_warned_about() -> None:
    """Measured: the tracker loses the object at realtime pace on the 2-core CPU, so such a
    run says so (log and metrics.json notes); a pose oracle, offline pace or a GPU does not."""
    import torch

    from neuralfeels_sem.tasks.map import tracked_realtime_caveat

    cpu = torch.device("cpu")
    caveat = tracked_realtime_caveat("track", "realtime", cpu)
    assert caveat.startswith("mapping.pose=track at sensor.pace=realtime on a CPU")
    assert "sensor.pace=offline" in caveat and "mapping.pose=gt" in caveat
    assert tracked_realtime_caveat("gt", "realtime", cpu) is None
    assert tracked_realtime_caveat("track_known_shape", "offline", cpu) is None
    assert tracked_realtime_caveat("track", "realtime", torch.device("cuda")) is None


def test_map_lag_reads_a_finished_run(tiny_run: Path, tmp_path: Path, capsys) -> None:
    from neuralfeels_sem.bench.map_lag import SERIES, main

    out = tmp_path / "lag.json"
    picture = tmp_path / "lag.png"
    main(
        [str(tiny_run), str(tmp_path), "--every", "0.5", "--out", str(out), "--plot", str(picture)]
    )
    assert picture.stat().st_size > 0
    (record,) = json.loads(out.read_text())  # tmp_path holds no run: skipped
    curve = json.loads((tiny_run / "metrics.json").read_text())["matching_mean_class_curve"]
    value_at = {p[1]: p[2] for p in curve}
    times = [r["time_s"] for r in record["rows"]]
    assert times == sorted(set(times)) and times[-1] == curve[-1][1]  # the run's end is read
    assert [r["field"] for r in record["rows"]] == [value_at[t] for t in times]
    # One curve point per half second at most (the latest by then), and the end.
    assert times[0] == curve[0][1] and len(times) <= int(curve[-1][1] / 0.5) + 2
    last = record["rows"][-1]
    assert last["readings"] is not None and 0.0 <= last["placement"] <= 100.0
    assert set(record["first_reached_s"]) == set(SERIES)
    assert "plushie seed 0 scripted: first at 90 % mean-class" in capsys.readouterr().out
