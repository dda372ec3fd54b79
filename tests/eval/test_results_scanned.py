"""The results page's section for scanned meshes with drawn layouts (object.layout_seed)."""

from __future__ import annotations

from pathlib import Path

from tests.eval.test_results_page import cells, generate, run_metrics, section
from tests.viz.test_sweep_plots import write_job


def scanned_metrics(mesh: str, layout_seed: int, mean_class: float) -> dict:
    made = {"mesh": mesh, "size_m": 0.19, "layout_seed": layout_seed, "sub_seed": 0,
            "materials": ["metal", "wood", "fabric"], "regions": ["half", "insert"]}  # fmt: skip
    return run_metrics(
        mean_class, 90.0, 33.3, 60.0, "metal",
        accuracy=0.97, coverage=0.7, oracles=["object_pose"],
        uncertainty={"auroc": 0.9}, config={"object": mesh, "object_layout": made},
    )  # fmt: skip


def write_scanned(sweep: Path, runs: list[tuple[str, int, float]], extra: list[str]) -> None:
    for k, (mesh, layout, value) in enumerate(runs):
        overrides = ["experiment=scanned_objects", f"object.name={mesh}"]
        write_job(sweep, str(k), [*overrides, f"object.layout_seed={layout}", "seed=0", *extra],
                  scanned_metrics(mesh, layout, value))  # fmt: skip


def test_scanned_meshes_get_a_row_per_layout_a_mean_and_the_lowest(tmp_path: Path) -> None:
    sweep = tmp_path / "multirun" / "scanned"
    runs = [("MustardBottle", 0, 91.0), ("MustardBottle", 1, 75.0), ("FoamBrick", 0, 95.0)]
    write_scanned(sweep, runs, [])
    page = generate(tmp_path, sweep)
    part = section(page, "Scanned meshes")
    assert "Setting: today's defaults (oracles: pose)." in part
    assert "at or above 80 %: 2 of 3 layouts; lowest 75.0 (MustardBottle, layout 1)" in part
    row = cells(part, "FoamBrick")
    assert row[1:] == ["19 cm", "0", "3: half, insert", "1", "95.0", "33.3 (metal)", "97.0",
                       "70.0", "0.90", "-"]  # fmt: skip
    assert cells(part, "**mean**")[5] == "**87.0 ± 10.6**"
    assert cells(part, "**mean**")[-1] == "-"  # no run's touches had a ground truth
    # Their own section only: neither a settings table nor the generated objects'.
    assert "layout_seed" not in section(page, "Other settings")
    assert "## Generated objects" not in page


def test_active_runs_on_scanned_meshes_beside_their_scripted_runs(tmp_path: Path) -> None:
    """An active-touch sweep of the scanned layouts is compared, layout by layout, with the
    scripted (default) run of the same mesh and layout from another sweep."""
    reference, active = tmp_path / "multirun" / "scanned", tmp_path / "multirun" / "active"
    write_scanned(reference, [("FoamBrick", 0, 71.0), ("FoamBrick", 1, 60.0)], [])
    write_scanned(active, [("FoamBrick", 1, 80.0)], ["sensor.policy=active"])
    page = generate(tmp_path, reference, active)
    row = cells(section(page, "Active touch"), "FoamBrick, layout 1")
    assert row[3] == "60.0†" and row[6] == "80.0" and row[9] == "+20.0"
    scanned = section(page, "Scanned meshes")
    assert "Setting: `sensor.policy=active` (oracles: pose)." in scanned


def test_runs_of_one_setting_are_pooled_over_sweeps(tmp_path: Path) -> None:
    """A sweep per mapping seed: one table per setting, each layout's runs averaged."""
    first, second = tmp_path / "multirun" / "s0", tmp_path / "multirun" / "s1"
    write_scanned(first, [("FoamBrick", 0, 70.0), ("FoamBrick", 1, 90.0)], [])
    write_scanned(second, [("FoamBrick", 0, 80.0)], [])
    part = section(generate(tmp_path, first, second), "Scanned meshes")
    assert part.count("### ") == 1 and "multirun/s0`, `" in part and "multirun/s1`\n" in part
    assert cells(part, "FoamBrick")[4:6] == ["2", "75.0"]  # layout 0: both seeds
    assert "1 of 2 layouts; lowest 75.0 (FoamBrick, layout 0)" in part
