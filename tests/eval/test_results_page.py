"""The results page generator on small fake run and sweep directories."""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from neuralfeels_sem.tasks.results_page import main
from tests.viz.test_sweep_plots import write_job

SIM_CONFIG = {
    "seed": 0,
    "sensor": {"name": "sim", "rgbd": {"depth_noise": "none"}},
    "object": {"name": "plushie"},
    "classifier": {"_target_": "neuralfeels_sem.perception.classifier.MaterialClassifier"},
    "mapping": {
        "pose": "gt",
        "mapper": {"camera_mask": "gt", "tactile_depth": {"source": "gt"}},
    },
}


def run_metrics(
    mean_class: float,
    matching: float,
    majority_mean_class: float,
    majority_matching: float,
    material: str,
    mesh: float = 90.0,
    fscore: float = 0.99,
    accuracy: float = 0.98,
    coverage: float = 0.75,
    all_touches: float = 0.735,
    **extra,
) -> dict:
    return {
        "matching_mean_class_pct": mean_class,
        "matching_pct": matching,
        "matching_mesh_pct": mesh,
        "fscore_5mm": fscore,
        "baseline_majority": {
            "matching_mean_class_pct": majority_mean_class,
            "matching_pct": majority_matching,
            "material": material,
        },
        "margin_over_majority": {
            "matching_mean_class_pct": mean_class - majority_mean_class,
            "matching_pct": matching - majority_matching,
        },
        "classifier_accuracy": {
            "overall": accuracy,
            "coverage": coverage,
            "accuracy_all_touches": all_touches,
        },
        "wall_s": 70.0,
        **extra,
    }


def cells(page: str, first: str) -> list[str]:
    """The cells of the table row whose first cell is `first`."""
    for line in page.splitlines():
        parts = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and parts[0] == first:
            return parts
    raise AssertionError(f"no row {first!r} in:\n{page}")


def table_rows(page: str) -> list[list[str]]:
    """The cells of every table row of `page` (header and separator rows left out)."""
    lines = [line for line in page.splitlines() if line.startswith("|")]
    return [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines[2:]]


def section(page: str, title: str) -> str:
    return page.split(f"## {title}\n", 1)[1].split("\n## ", 1)[0]


def generate(tmp_path: Path, *dirs: Path) -> str:
    out = tmp_path / "docs" / "results.md"
    assert main(["--out", str(out), *map(str, dirs)]) == 0
    return out.read_text()


PATCHED = [97.0, 91.0, 95.0, 99.0]  # mean-class per seed 0-3


@pytest.fixture
def object_sweep(tmp_path: Path) -> Path:
    return write_object_sweep(tmp_path)


def write_object_sweep(tmp_path: Path) -> Path:
    """multi_material-like sweep: patched_toy x 4 seeds, patchwork x 2, yarn_ball x 2, one failure."""
    sweep = tmp_path / "multirun" / "mm"
    k = 0
    bookkeeping = ["experiment=multi_material", "launcher=joblib"]
    for seed, value in enumerate(PATCHED):
        metrics = run_metrics(
            value,
            matching=96.0 + seed,
            majority_mean_class=50.0,
            majority_matching=54.0 + seed,
            material="plastic",
            mesh=90.0 + seed,
            fscore=0.99 + 0.002 * seed,
            accuracy=0.99,
            coverage=0.6 + 0.1 * seed,
            oracles=["object_pose", "camera_mask"],
        )
        write_job(sweep, str(k), [*bookkeeping, "object=patched_toy", f"seed={seed}"], metrics)
        k += 1
    for seed, value in ((0, 80.0), (1, 70.0)):
        metrics = run_metrics(value, 85.0, 25.0, 33.0, "plastic", oracles=["object_pose"])
        # patchwork's runs record one oracle less: the source line says so per group.
        write_job(sweep, str(k), [*bookkeeping, "object=patchwork", f"seed={seed}"], metrics)
        k += 1
    for seed, (acc, cov) in enumerate(((1.0, 0.8), (0.9, 0.6))):
        metrics = run_metrics(
            100.0,
            100.0,
            100.0,
            100.0,
            "fabric",
            fscore=0.98,
            accuracy=acc,
            coverage=cov,
            all_touches=acc * cov,
            oracles=["object_pose"],
        )
        write_job(sweep, str(k), [*bookkeeping, "object=yarn_ball", f"seed={seed}"], metrics)
        k += 1
    write_job(sweep, str(k), ["object=patchwork", "seed=2"], None, error="NoDataError: no touches")
    return sweep


def test_multi_material_row_holds_the_per_seed_figures_and_the_floor(
    tmp_path: Path, object_sweep: Path
) -> None:
    page = generate(tmp_path, object_sweep)
    multi = section(page, "Multi-material objects")
    row = cells(multi, "`patched_toy`")
    assert row[1] == "pose, mask"  # the simulator ground truth these runs used
    row = row[:1] + row[2:]
    assert row[1] == "0-3"
    assert row[2] == "97.0, 91.0, 95.0, 99.0"
    mean, std = statistics.mean(PATCHED), statistics.stdev(PATCHED)
    assert row[3] == f"**{mean:.1f} ± {std:.1f}**" == "**95.5 ± 3.4**"
    assert row[4] == "50.0 (plastic)"
    assert row[5] == f"+{mean - 50.0:.1f}"
    assert row[6] == "97.5 (55.5)"  # matching beside the majority map's matching
    assert row[7] == "91.5"  # on mesh
    assert row[8] == "0.993"
    assert row[9] == "99.0"  # classifier on judged touches, %
    assert row[10] == "75.0"  # coverage, %
    row = cells(multi, "`patchwork`")
    assert row[1:7] == ["pose", "0-1", "80.0, 70.0", "**75.0 ± 7.1**", "25.0 (plastic)", "+50.0"]
    # The single-material object is not scored by matching.
    assert "yarn_ball" not in multi


def test_single_material_objects_are_reported_by_the_classifier(
    tmp_path: Path, object_sweep: Path
) -> None:
    page = generate(tmp_path, object_sweep)
    single = section(page, "Single-material objects")
    row = cells(single, "`yarn_ball`")
    all_touches = [100 * 1.0 * 0.8, 100 * 0.9 * 0.6]
    spread = f"{statistics.stdev(all_touches):.1f}"
    assert row[1:] == [
        "pose",
        "2",
        "0-1",
        "95.0 ± 7.1",
        "70.0 ± 14.1",
        f"67.0 ± {spread}",
        "100.0 ± 0.0",  # the map in the object's one material
        "0.980 ± 0.000",
    ]
    assert "mean-class" not in single.split("|", 1)[1]


def test_header_sources_oracles_and_failures(tmp_path: Path, object_sweep: Path) -> None:
    page = generate(tmp_path, object_sweep)
    assert "generated" in page.splitlines()[2].lower()
    assert "python -m neuralfeels_sem.tasks.results_page --out" in page
    assert str(object_sweep.name) in page.split("```")[1]
    sources = section(page, "Sources")
    assert "(sweep: 8 runs with metrics.json; 1 failed: 8)" in sources
    assert (
        "  - oracles (4 runs, from metrics.json): ground-truth object pose (mapping.pose=gt); "
        "the simulator's camera object mask" in sources
    )
    assert (
        "  - oracles (4 runs, from metrics.json): ground-truth object pose (mapping.pose=gt)\n"
        in sources
    )
    assert "  - machine/load: not recorded; wall time per run 70 s" in sources


def test_ablation_sweep_gets_a_settings_table(tmp_path: Path) -> None:
    sweep = tmp_path / "ablation"
    k = 0
    for radius, value in (("0.02", 90.0), ("0.01", 60.0)):
        for seed in (0, 1):
            metrics = run_metrics(value + seed, 95.0, 50.0, 54.0, "plastic", fscore=0.9)
            overrides = [
                "object=patched_toy",
                f"mapping.mapper.label_vote_radius={radius}",
                "sensor.duration_s=3",
            ]
            write_job(sweep, str(k), [*overrides, f"seed={seed}"], metrics)
            k += 1
    page = generate(tmp_path, sweep)
    other = section(page, "Other settings")
    assert "Every run here: `sensor.duration_s=3`." in other
    row = cells(other, "object=patched_toy, mapping.mapper.label_vote_radius=0.01")
    assert row[1:] == [
        "not recorded",  # oracles: neither metrics.json nor a config says
        "0-1",
        "60.0, 61.0",
        "**60.5 ± 0.7**",
        "50.0 (plastic)",
        "+10.5",
        "95.0 (54.0)",
        "0.900",
        "70",  # wall time per run, s
    ]
    assert cells(other, "object=patched_toy, mapping.mapper.label_vote_radius=0.02")[4] == (
        "**90.5 ± 0.7**"
    )
    assert "frames dropped" not in other  # only where a run streamed at sensor.pace=realtime
    # Runs with settings never reach the object tables.
    assert "No default-config multi-material runs." in page


def test_a_setting_pools_runs_only_with_the_same_oracles(tmp_path: Path) -> None:
    sweep = tmp_path / "ablation"
    for k, oracles in enumerate((["object_pose"], ["object_pose", "camera_mask"])):
        metrics = run_metrics(80.0 + k, 95.0, 50.0, 54.0, "plastic", oracles=oracles)
        write_job(sweep, str(k), ["object=patched_toy", "seed=0", "sensor.duration_s=3"], metrics)
    rows = table_rows(section(generate(tmp_path, sweep), "Other settings"))
    assert [(r[1], r[4]) for r in rows] == [
        ("pose", "**80.0 ± 0.0**"),
        ("pose, mask", "**81.0 ± 0.0**"),
    ]


def test_runs_with_other_oracles_get_their_own_row_and_a_perception_table(
    tmp_path: Path,
) -> None:
    sweep = tmp_path / "perception"
    for k, (oracles, value) in enumerate(((["object_pose"], 90.0), ([], 80.0))):
        metrics = run_metrics(value, 95.0, 50.0, 54.0, "plastic", oracles=oracles)
        metrics["perception"] = {
            "camera_mask": "gt" if oracles else "segment",
            "camera_mask_iou": 0.9 + 0.01 * k,
            "camera_frames_skipped": 0,
            "tactile_depth_mae_mm": 0.2,
        }
        preset = "perception=oracle_camera_mask" if oracles else "perception=realistic"
        write_job(sweep, str(k), ["object=patched_toy", "seed=0", preset], metrics)
    page = generate(tmp_path, sweep)
    multi = section(page, "Multi-material objects")
    rows = {tuple(r[:2]): r for r in table_rows(multi)}
    assert rows[("`patched_toy`", "pose")][4] == "**90.0 ± 0.0**"
    assert rows[("`patched_toy`", "none")][4] == "**80.0 ± 0.0**"
    perception = section(page, "Perception against the simulator's ground truth")
    rows = {tuple(r[:2]): r for r in table_rows(perception)}
    assert rows[("`patched_toy`", "none")][2:] == [
        "1",
        "0.910 ± 0.000",
        "0.0 ± 0.0",
        "n/a",
        "0.200 ± 0.000",
    ]
    # With the simulator's mask nothing was segmented: no camera figures.
    assert rows[("`patched_toy`", "pose")][3:5] == ["n/a", "n/a"]


def test_single_run_oracles_come_from_its_config(tmp_path: Path) -> None:
    run = tmp_path / "outputs" / "map" / "plushie"
    (run / ".hydra").mkdir(parents=True)
    (run / ".hydra" / "config.yaml").write_text(yaml.safe_dump(SIM_CONFIG))
    (run / ".hydra" / "overrides.yaml").write_text(
        yaml.safe_dump(["sensor=sim", "perception=oracle"])
    )
    metrics = run_metrics(
        70.0, 97.0, 50.0, 96.0, "fabric", machine={"cpus": 2}, load_avg=[1.2, 0.9, 0.7]
    )
    metrics["config"] = {"object": "plushie", "seed": 0}
    (run / "metrics.json").write_text(json.dumps(metrics))
    page = generate(tmp_path, run)
    assert cells(section(page, "Multi-material objects"), "`plushie`")[2:5] == [
        "0",
        "70.0",
        "**70.0 ± 0.0**",
    ]
    line = section(page, "Sources")
    assert "(run directory)" in line
    assert "(from .hydra/config.yaml)" in line
    for words in ("ground-truth object pose", "camera object mask", "contact depth", "noise-free"):
        assert words in line
    assert "ground-truth material labels" not in line
    assert "machine/load: cpus 2; 1-minute load average at the end of the runs 1.2" in line


def test_bad_input_is_one_line_and_exit_code_2(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    empty = tmp_path / "empty"
    (empty / "0").mkdir(parents=True)
    assert main([str(empty)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and str(empty) in err and "\n" not in err
    missing = tmp_path / "nope"
    proc = subprocess.run(
        [sys.executable, "-m", "neuralfeels_sem.tasks.results_page", str(missing)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"error: {missing}: no such directory"


def test_without_out_the_page_goes_to_stdout(
    tmp_path: Path, object_sweep: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main([str(object_sweep)]) == 0
    assert capsys.readouterr().out.startswith("# Results\n")


def test_readme_table_is_rewritten_between_its_markers(tmp_path: Path, object_sweep: Path) -> None:
    from neuralfeels_sem.eval.results_page import README_BEGIN, README_END

    readme = tmp_path / "README.md"
    readme.write_text(f"# Front\n\nbefore\n{README_BEGIN}\n| old |\n{README_END}\nafter\n")
    out = tmp_path / "docs" / "results.md"
    assert main(["--out", str(out), "--readme", str(readme), str(object_sweep)]) == 0
    text = readme.read_text()
    assert text.startswith("# Front\n\nbefore\n") and text.endswith("after\n")
    assert "| old |" not in text
    block = text.split(README_BEGIN)[1].split(README_END)[0].strip()
    table, stated = block.rsplit("\n\n", 1)
    assert table.strip() == section(out.read_text(), "Multi-material objects").strip()
    # the front page says which code, when and where the figures come from
    assert stated.startswith("*Runs: code version not recorded; finished 20")
    assert "; machine and load: " in stated and stated.endswith(".*")


def test_readme_without_markers_is_one_line(
    tmp_path: Path, object_sweep: Path, capsys: pytest.CaptureFixture
) -> None:
    readme = tmp_path / "README.md"
    readme.write_text("# Front\n")
    assert main(["--readme", str(readme), str(object_sweep)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "README.md" in err and "\n" not in err
    assert readme.read_text() == "# Front\n"


def write_bench(path: Path, results: dict) -> Path:
    report = {"machine": {"cpu_count": 2}, "started": "2026-11-24T21:25:12", "results": results}
    path.write_text(json.dumps(report))
    return path


def test_speed_section_shows_the_bench_figures_with_their_load(
    tmp_path: Path, object_sweep: Path
) -> None:
    bench = write_bench(
        tmp_path / "bench.json",
        {
            "mapper": {"steps_per_s": 8.04, "frame_points_ms": 23.3, "load_avg_1min": 1.75},
            "sim": {"full_frames_per_s": 28.93},  # no load recorded
            "pose": {"error": "RuntimeError: broken"},  # a failed benchmark shows nothing
        },
    )
    out = tmp_path / "results.md"
    assert main(["--out", str(out), "--bench", str(bench), str(object_sweep)]) == 0
    page = out.read_text()
    assert f"--bench {bench}" in page.split("```")[1]
    speed = section(page, "Speed")
    assert "| mapper step (default config) | 8.04 steps/s | 1.8 | `mapper.steps_per_s` |" in speed
    assert "| simulated rig, 4 DIGITs + RGB-D | 28.93 frames/s | - |" in speed
    assert "started 2026-11-24T21:25:12; cpu_count 2" in speed
    assert "pose" not in speed.split("| --- |")[-1]
    assert "## Speed" not in generate(tmp_path / "again", object_sweep)  # only with --bench


def test_each_bench_report_gets_its_own_speed_table(tmp_path: Path, object_sweep: Path) -> None:
    cpu = write_bench(tmp_path / "bench.json", {"mapper": {"steps_per_s": 8.04}})
    gpu = tmp_path / "bench_gpu.json"
    gpu.write_text(
        json.dumps(
            {
                "machine": {"cpu_count": 16, "cuda_device": "NVIDIA H100 80GB HBM3"},
                "started": "2026-11-26T08:45:31",
                "results": {
                    "field": {"cuda_paper_log2_24_sparse": {"steps_per_s": 232.3}},
                    "mapper": {"default_run_cuda_log2_24": {"realtime_factor": 0.207}},
                },
            }
        )
    )
    out = tmp_path / "results.md"
    assert (
        main(["--out", str(out), "--bench", str(cpu), "--bench", str(gpu), str(object_sweep)]) == 0
    )
    page = out.read_text()
    assert f"--bench {cpu} --bench {gpu}" in page.split("```")[1]
    speed = section(page, "Speed")
    first, second = speed.split(f"From `{gpu.as_posix()}`")
    assert "8.04 steps/s" in first and "232.3" not in first
    assert "cuda_device NVIDIA H100 80GB HBM3" in second
    assert "| field step on the GPU, 4096 points, 2^24 | 232.3 steps/s | - |" in second
    assert "| default run on the GPU, 2^24 table: sensor time / loop time | 0.207 x |" in second


def test_a_bad_bench_report_is_one_line(
    tmp_path: Path, object_sweep: Path, capsys: pytest.CaptureFixture
) -> None:
    bad = tmp_path / "bench.json"
    bad.write_text("{not json")
    assert main(["--bench", str(bad), str(object_sweep)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {bad}: not a bench report") and "\n" not in err
    assert main(["--bench", str(tmp_path / "none.json"), str(object_sweep)]) == 2
    assert "run `make bench` first" in capsys.readouterr().err


def test_single_material_runs_with_a_setting_get_classifier_figures(tmp_path: Path) -> None:
    sweep = tmp_path / "single"
    metrics = run_metrics(100.0, 100.0, 100.0, 100.0, "wood", accuracy=0.9, coverage=0.5)
    write_job(sweep, "0", ["object=candle_holder", "seed=0", "sensor.duration_s=3"], metrics)
    other = section(generate(tmp_path, sweep), "Other settings")
    assert "classifier acc. on judged touches %" in other
    assert "mean-class % per seed" not in other  # a constant map scores 100 % there
    assert cells(other, "object=candle_holder")[4:6] == ["90.0 ± 0.0", "50.0 ± 0.0"]


def test_a_default_run_repeated_in_another_source_counts_once(
    tmp_path: Path, object_sweep: Path
) -> None:
    # A live-view source reruns its baseline (today's defaults, patched_toy seed 0) beside
    # the run with the view: the object table must not hold seed 0 twice.
    view = tmp_path / "multirun" / "view"
    base = run_metrics(12.0, 96.0, 50.0, 54.0, "plastic", oracles=["object_pose", "camera_mask"])
    write_job(view, "0", ["object=patched_toy", "seed=0"], base)
    write_job(view, "1", ["object=patched_toy", "seed=0", "viz.live=rerun"], base)
    page = generate(tmp_path, object_sweep, view)
    row = cells(section(page, "Multi-material objects"), "`patched_toy`")
    assert row[3] == ", ".join(f"{v:.1f}" for v in PATCHED)  # the repeat's 12.0 left out
    assert "viz.live=rerun" in section(page, "Other settings")


def test_a_directory_named_twice_counts_once(tmp_path: Path, object_sweep: Path) -> None:
    once = generate(tmp_path, object_sweep)
    twice = generate(tmp_path, object_sweep, Path(f"{object_sweep}/"), object_sweep)
    assert twice == once


def test_a_report_of_part_of_the_bench_says_what_ran(tmp_path: Path, object_sweep: Path) -> None:
    whole = write_bench(tmp_path / "bench.json", {"mapper": {"steps_per_s": 8.04}})
    part = tmp_path / "bench_gpu.json"
    report = json.loads(whole.read_text()) | {"ran": "the mapper bench's GPU runs alone"}
    part.write_text(json.dumps(report))
    out = tmp_path / "results.md"
    assert (
        main(["--out", str(out), "--bench", str(whole), "--bench", str(part), str(object_sweep)])
        == 0
    )
    first, second = section(out.read_text(), "Speed").split(f"From `{part.as_posix()}`")
    assert "(`make bench`, started" in first
    assert second.startswith(" (the mapper bench's GPU runs alone, started 2026-11-24T21:25:12")
