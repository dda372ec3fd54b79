"""Experiment plots from a fake sweep directory (jobs' overrides and metrics.json)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from neuralfeels_sem.eval.aggregate import summarize
from neuralfeels_sem.viz.finger_material_plots import finger_material_table
from neuralfeels_sem.viz.sweep_plots import plot_experiment
from tests.viz.images import assert_png

FINGERS = ("index", "middle", "ring", "thumb")
SINGLE = {
    "plastic_toy": "plastic",
    "candle_holder": "metal",
    "fabric_toy": "fabric",
    "yarn_ball": "fabric",
}


def write_job(
    sweep: Path, name: str, overrides: list[str], metrics: dict | None, error: str | None = None
) -> None:
    job = sweep / name
    (job / ".hydra").mkdir(parents=True)
    (job / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
    if metrics is not None:
        (job / "metrics.json").write_text(json.dumps(metrics))
    if error is not None:
        (job / "error.txt").write_text(error)


def map_metrics(accuracy: dict, final: float, start: float = 40.0) -> dict:
    per_finger = {f: a for f, a in accuracy.items()}
    return {
        "matching_pct": final,
        "matching_curve": [[0, 0.0, start], [5, 0.5, (start + final) / 2], [10, 1.0, final]],
        "fscore_5mm": 0.8,
        "chamfer_mm": 3.0,
        "classifier_accuracy": {
            "overall": float(np.mean([a for a in accuracy.values() if a is not None])),
            "per_finger": per_finger,
            "per_finger_material": {
                f: {m: a for m, a in row.items()} for f, row in accuracy.items()
            }
            if isinstance(next(iter(accuracy.values())), dict)
            else {},
        },
    }


def single_material_sweep(sweep: Path) -> dict[tuple[str, str], list[float]]:
    """Objects x 2 seeds, one failed job, one job without metrics; returns the accuracies written."""
    written: dict[tuple[str, str], list[float]] = {}
    rng = np.random.default_rng(0)
    k = 0
    for obj, material in SINGLE.items():
        for seed in (0, 1):
            table = {f: {material: float(rng.uniform(0.2, 1.0))} for f in FINGERS}
            table["thumb"][material] = (
                None if obj == "plastic_toy" and seed == 0 else table["thumb"][material]
            )
            for f in FINGERS:
                if table[f][material] is not None:
                    written.setdefault((f, material), []).append(table[f][material])
            metrics = map_metrics({f: table[f][material] for f in FINGERS}, final=70.0 + seed)
            metrics["classifier_accuracy"]["per_finger_material"] = table
            write_job(sweep, str(k), [f"object={obj}", f"seed={seed}"], metrics)
            k += 1
    write_job(
        sweep, str(k), ["object=plastic_toy", "seed=2"], None, error="NoDataError: no touches"
    )
    write_job(sweep, str(k + 1), ["object=yarn_ball", "seed=2"], None)
    return written


def test_single_material_sweep_plots(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    written = single_material_sweep(sweep)
    summary = summarize(sweep)
    paths = plot_experiment(summary, sweep)
    names = {p.name for p in paths}
    assert {
        "single_material_heatmap.png",
        "single_material_bars.png",
        "matching_curves.png",
        "ablation.png",
    } <= names
    for path in paths:
        assert path.parent == sweep
        assert_png(path)
    # The heatmap's numbers are the means of what the jobs wrote.
    runs = [json.loads((sweep / j / "metrics.json").read_text()) for j in map(str, range(8))]
    fingers, materials, values = finger_material_table(runs)
    assert fingers == list(FINGERS) and materials == ["fabric", "metal", "plastic"]
    for (finger, material), accuracies in written.items():
        cell = values[fingers.index(finger), materials.index(material)]
        assert np.nanmean(cell) == pytest.approx(100 * np.mean(accuracies))
        assert np.sum(~np.isnan(cell)) == len(accuracies)


def test_ablation_sweep_plots(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    k = 0
    for concat in ("true", "false"):
        for obj in ("patched_toy", "plushie"):
            for seed in (0, 1):
                final = (80.0 if concat == "true" else 65.0) + seed
                write_job(
                    sweep,
                    str(k),
                    [
                        f"model.material.concat_sdf_features={concat}",
                        f"object={obj}",
                        f"seed={seed}",
                    ],
                    {
                        "matching_pct": final,
                        "matching_curve": [[0, 0.0, 40.0], [10, 1.0, final]],
                        "fscore_5mm": 0.9,
                    },
                )
                k += 1
    paths = plot_experiment(summarize(sweep), sweep)
    assert {p.name for p in paths} == {"matching_curves.png", "ablation.png"}
    for path in paths:
        assert_png(path)


def test_nothing_to_plot_and_broken_files_do_not_crash(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    write_job(sweep, "0", ["seed=0"], None, error="DataError: missing")
    write_job(
        sweep,
        "1",
        ["seed=1"],
        {"matching_curve": "garbage", "classifier_accuracy": {"per_finger_material": 3}},
    )
    summary = summarize(sweep)
    assert plot_experiment(summary, sweep) == []
    # A job listed as ok whose metrics.json is unreadable or gone is skipped.
    (sweep / "1" / "metrics.json").write_text("{not json")
    summary["jobs"].append({"job": "7", "overrides": {"seed": "7"}, "status": "ok", "metrics": {}})
    assert plot_experiment(summary, sweep) == []
    assert plot_experiment({}, sweep) == []


def test_classifier_sweep_plots_per_sensor(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    for seed, thumb in enumerate((0.90, 0.96)):
        write_job(sweep, str(seed), ["task=train_classifier", f"seed={seed}"], None)
        report = {
            "test_accuracy": 0.97,
            "per_sensor": {"thumb": thumb, "index": 0.99, "ring": 1.0, "middle": 0.98},
        }
        (sweep / str(seed) / "report.json").write_text(json.dumps(report))
    summary = summarize(sweep)
    paths = plot_experiment(summary, sweep)
    assert [p.name for p in paths] == ["classifier_per_sensor.png"]
    assert_png(paths[0])


def test_ablation_without_object_axis_names_the_shared_object(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    fingers = ("[index,middle,ring,thumb]", "[index,ring]")
    for k, (value, seed) in enumerate((f, s) for f in fingers for s in (0, 1)):
        write_job(
            sweep,
            str(k),
            ["object=patched_toy", f"sensor.fingers={value}", f"seed={seed}"],
            {"matching_pct": 70.0 + k, "matching_curve": [[0, 0.0, 40.0], [10, 1.0, 70.0 + k]]},
        )
    summary = summarize(sweep)
    assert [g["group"] for g in summary["groups"]] == [
        {"sensor.fingers": f} for f in sorted(fingers)
    ]
    paths = plot_experiment(summary, sweep)
    assert {p.name for p in paths} == {"matching_curves.png", "ablation.png"}
    for path in paths:
        assert_png(path)


def test_heatmap_pools_touches_rather_than_averaging_runs() -> None:
    from neuralfeels_sem.viz.finger_material_plots import pooled_finger_material

    def run(correct: int, judged: int, abstentions: int = 0) -> dict:
        cell = {
            "accuracy": correct / judged,
            "correct": correct,
            "judged": judged,
            "abstentions": abstentions,
        }
        return {
            "classifier_accuracy": {
                "per_finger_material": {"ring": {"metal": correct / judged}},
                "counts": {"ring": {"metal": cell}},
            }
        }

    # one wrong touch in one run, 99 right and 100 abstained in another
    runs = [run(0, 1), run(99, 99, abstentions=100)]
    pooled = pooled_finger_material(runs, ["ring", "thumb"], ["metal"])
    accuracy, judged = pooled["accuracy"], pooled["judged"]
    assert accuracy[0, 0] == pytest.approx(99.0) and judged[0, 0] == 100
    assert pooled["touches"][0, 0] == 200
    assert pooled["coverage"][0, 0] == pytest.approx(50.0)
    assert pooled["accuracy_all_touches"][0, 0] == pytest.approx(49.5)
    assert np.isnan(accuracy[1, 0]) and judged[1, 0] == 0
    _, _, values = finger_material_table(runs)
    assert np.nanmean(values[0, 0]) == pytest.approx(50.0)  # what a mean of runs shows
    without_counts = [{"classifier_accuracy": {"per_finger_material": {}}}]
    assert pooled_finger_material(without_counts, ["ring"], ["metal"]) is None


def write_maps_picture(path: Path, colour: tuple[float, float, float]) -> None:
    """A stand-in for a job's material_maps.png: three coloured views side by side."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 2.2))
    for k, axis in enumerate(fig.subplots(1, 3)):
        axis.imshow(np.ones((20, 20, 3)) * np.asarray(colour) * (0.5 + 0.25 * k))
    fig.savefig(path, dpi=60)


def test_maps_grid_tiles_every_job_with_its_map(tmp_path: Path) -> None:
    from neuralfeels_sem.viz.maps_grid import tile_title

    colours = [(1.0, 0.2, 0.2), (0.2, 0.8, 0.2), (0.2, 0.2, 1.0)]
    for k, colour in enumerate(colours):
        metrics = map_metrics({f: 0.9 for f in FINGERS}, final=80.0 + k)
        metrics["matching_mean_class_pct"] = 70.0 + k
        metrics["baseline_majority"] = {"matching_mean_class_pct": 50.0}
        write_job(tmp_path, str(k), ["object=random", f"object.seed={1000 + k}"], metrics)
        write_maps_picture(tmp_path / str(k) / "material_maps.png", colour)
    # A job without its picture (a run stopped before its maps) is left out, not drawn blank.
    metrics = map_metrics({f: 0.9 for f in FINGERS}, final=60.0)
    write_job(tmp_path, "3", ["object=random", "object.seed=1003"], metrics)
    written = plot_experiment(summarize(tmp_path), tmp_path)
    grid = tmp_path / "maps_grid.png"
    assert grid in written
    pixels = assert_png(grid, min_width=600).astype(int)
    for colour in colours:  # every job's picture is in the grid
        target = (np.asarray(colour) * 0.75 * 255).astype(int)
        assert (np.abs(pixels - target).max(axis=-1) < 12).any(), colour
    # The tiles are titled with the setting, the mean-class matching and the majority map's.
    metrics = {
        "matching_mean_class_pct": 71.0,
        "baseline_majority": {"matching_mean_class_pct": 50},
    }
    assert tile_title("seed=1001", metrics) == "seed=1001: mean-class 71.0% (majority 50.0%)"
    assert tile_title("seed=1003", {}) == "seed=1003"


def test_a_sweep_of_many_objects_plots_readably(tmp_path: Path) -> None:
    """experiment=unseen_objects: 20 settings of one axis. The curves' legend stays short
    (the mean over runs, the majority map) and no axes collapse under it; the bars run
    along the axis, one per setting."""
    import warnings

    sweep = tmp_path / "sweep"
    for k in range(20):
        final = 70.0 + k
        metrics = {
            "matching_mean_class_pct": final,
            "matching_mean_class_curve": [[0, 0.0, 25.0], [10, 1.0, final]],
            "matching_pct": final + 5.0,
            "matching_curve": [[0, 0.0, 50.0], [10, 1.0, final + 5.0]],
            "baseline_majority": {"matching_mean_class_pct": 25.0 + (k % 2) * 25.0},
        }
        write_job(sweep, str(k), [f"object.seed={1000 + k}", "seed=0"], metrics)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns when a legend squeezes the axes away
        paths = plot_experiment(summarize(sweep), sweep)
    assert {p.name for p in paths} == {"matching_curves.png", "ablation.png"}
    curves = assert_png(sweep / "matching_curves.png")
    bars = assert_png(sweep / "ablation.png")
    assert curves.shape[0] < 800 and bars.shape[1] < 3000, (curves.shape, bars.shape)
