"""pose_curves.png: tracked runs' pose error over time, per object and setting."""

from __future__ import annotations

from neuralfeels_sem.viz.pose_sweep_plot import plot_pose_curves


def _run(obj: str, pose: str, seed: int, curve: list | None) -> tuple[dict, dict]:
    job = {"overrides": {"object": obj, "mapping.pose": pose, "seed": str(seed)}}
    metrics: dict = {"config": {"object": obj}}
    if curve is not None:
        metrics.update(pose_error_curve=curve, pose_error_mm=sum(r[2] for r in curve) / len(curve))
    return job, metrics


def test_tracked_runs_are_drawn_and_gt_runs_left_out(tmp_path) -> None:
    curve = [[0, 0.0, 0.0], [1, 0.1, 1.0], [2, 0.2, 2.0]]
    runs = [
        _run("patchwork", "track", 0, curve),
        _run("patchwork", "track", 1, curve),
        _run("kitchen_tool", "track", 0, curve),
        _run("kitchen_tool", "gt", 0, None),
    ]
    path = plot_pose_curves(runs, ["mapping.pose", "object", "seed"], tmp_path / "p.png")
    assert path == tmp_path / "p.png" and path.stat().st_size > 1000


def test_no_tracked_run_no_picture(tmp_path) -> None:
    runs = [_run("patchwork", "gt", 0, None)]
    assert plot_pose_curves(runs, ["mapping.pose"], tmp_path / "p.png") is None
    assert not (tmp_path / "p.png").exists()
