"""SIGINT / SIGTERM / kill -9 during a real (toy-sized) map run, then resume in place.

Slow: each case maps a few frames through the command line (about 20 s a run).
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from neuralfeels_sem.utils.paths import REPO_DIR
from tests.reliability.checks import assert_refused, tree_digest

pytestmark = pytest.mark.slow

TOY = [
    "object=plushie",
    "classifier=oracle",
    "sensor.duration_s=2.0",
    "sensor.fps=5",
    "sensor.rgbd.width=80",
    "sensor.rgbd.height=60",
    "mapping.mapper.warmup_steps=2",
    "mapping.mapper.steps_per_frame=1",
    "mapping.checkpoint_every=1",
    "eval.every_k_frames=1",
    "eval.num_surface_samples=500",
    "eval.image_views=1",
    "eval.image_size=32",
    "eval.mesh_resolution=24",
    "eval.shape_samples=500",
    "viz.progression_snapshots=4",
]
FRAMES = 10  # 2.0 s at 5 fps
ENV = dict(os.environ, HYDRA_FULL_ERROR="0", TQDM_DISABLE="1", OMP_NUM_THREADS="1")
SAME_IN_EVERY_RUN = (
    "matching_pct",
    "matching_mean_class_pct",
    "matching_curve",
    "matching_mean_class_curve",
    "trained_on",
    "fscore_5mm",
    "chamfer_mm",
    "classifier_accuracy",
    "frames",
    "frames_total",
)


def _start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, str(REPO_DIR / "run.py"), *TOY, *args],
        cwd=REPO_DIR,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _run(args: list[str]) -> subprocess.CompletedProcess:
    process = _start(args)
    out, err = process.communicate(timeout=300)
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


def _wait_for_checkpoints(run_dir: Path, count: int, process: subprocess.Popen) -> None:
    """Until checkpoint.pt has been (re)written `count` times: after frame count - 1, or
    later where a write outlasted a frame (the next checkpoint then waits for it)."""
    path, seen, last = run_dir / "checkpoint.pt", 0, None
    deadline = time.monotonic() + 300
    while seen < count:
        assert process.poll() is None, process.communicate()[1][-2000:]
        assert time.monotonic() < deadline
        stamp = path.stat().st_mtime_ns if path.exists() else None
        if stamp is not None and stamp != last:
            seen, last = seen + 1, stamp
        time.sleep(0.01)


def _metrics(run_dir: Path) -> dict:
    return json.loads((run_dir / "metrics.json").read_text())


def _checkpoint_frame(run_dir: Path) -> int:
    return int(torch.load(run_dir / "checkpoint.pt", weights_only=True)["frame_index"])


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_keeps_every_finished_frame_and_the_run_resumes(
    tmp_path: Path, signum: int
) -> None:
    run_dir = tmp_path / "run"
    process = _start([f"hydra.run.dir={run_dir}"])
    _wait_for_checkpoints(run_dir, 2, process)
    process.send_signal(signum)
    out, err = process.communicate(timeout=300)
    name = signal.Signals(signum).name
    result = subprocess.CompletedProcess(process.args, process.returncode, out, err)
    line = assert_refused(result, 128 + signum, f"interrupted ({name})", str(run_dir))
    assert f"mapping.resume={run_dir / 'checkpoint.pt'}" in line

    partial = _metrics(run_dir)
    assert partial["partial"] is True and partial["stopped_by"] == name
    last = partial["frames_total"] - 1
    assert last < FRAMES - 1
    assert _checkpoint_frame(run_dir) == last  # nothing after the last checkpoint was lost
    touches = (run_dir / "touches.csv").read_text().splitlines()
    assert touches[0].startswith("# partial")
    assert max(int(row.split(",")[0]) for row in touches[2:]) == last
    assert (run_dir / "material_maps.png").is_file()
    assert not (run_dir / "run.lock").exists()
    first_config = tree_digest(run_dir / ".hydra")

    resumed = _run([f"mapping.resume={run_dir / 'checkpoint.pt'}"])
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert f"run directory: {run_dir}" in resumed.stdout  # continued in place
    # The first segment's config stays; the resumed one's is written beside it.
    configs = tree_digest(run_dir / ".hydra")
    assert {k: v for k, v in configs.items() if k in first_config} == first_config
    assert len([k for k in configs if k.startswith("resumed_") and k.endswith("config.yaml")]) == 1
    final = _metrics(run_dir)
    assert final["partial"] is False and final["frames"] == FRAMES
    assert [s["partial"] for s in final["segments"]] == [True, False]
    assert final["segments"][0]["last_frame"] == last
    assert final["wall_s"] == pytest.approx(sum(s["wall_s"] for s in final["segments"]))
    assert [row[0] for row in final["matching_curve"]] == list(range(FRAMES))
    assert not (run_dir / "touches.csv").read_text().startswith("# partial")


def test_kill_9_at_a_random_frame_then_resume_gives_the_uninterrupted_result(
    tmp_path: Path,
) -> None:
    reference = _run([f"hydra.run.dir={tmp_path / 'reference'}"])
    assert reference.returncode == 0, reference.stderr[-3000:]

    run_dir = tmp_path / "killed"
    kill_after = random.Random(int(time.time())).randint(1, FRAMES - 2)
    process = _start([f"hydra.run.dir={run_dir}"])
    _wait_for_checkpoints(run_dir, kill_after, process)
    process.kill()
    process.communicate()
    assert (run_dir / "run.lock").is_file()  # left behind by the killed process

    resumed = _run([f"mapping.resume={run_dir / 'checkpoint.pt'}"])
    assert resumed.returncode == 0, (kill_after, resumed.stderr[-3000:])
    assert "which no longer runs" in resumed.stdout + resumed.stderr  # the stale lock
    expected, final = _metrics(tmp_path / "reference"), _metrics(run_dir)
    for key in SAME_IN_EVERY_RUN:
        assert final[key] == expected[key], (key, kill_after)
    assert len(final["segments"]) == 2
    assert (run_dir / "touches.csv").read_text() == (
        tmp_path / "reference" / "touches.csv"
    ).read_text()


@pytest.mark.parametrize(
    "signum, delay_s",
    [
        (signal.SIGINT, 0.3),  # during the imports
        (signal.SIGINT, 2.5),
        (signal.SIGINT, 6.0),
        (signal.SIGTERM, 0.3),
        (signal.SIGTERM, 4.0),
    ],
    ids=["SIGINT-0.3s", "SIGINT-2.5s", "SIGINT-6s", "SIGTERM-0.3s", "SIGTERM-4s"],
)
def test_a_signal_at_any_moment_ends_in_one_line(
    tmp_path: Path, signum: int, delay_s: float
) -> None:
    run_dir = tmp_path / "run"
    process = _start([f"hydra.run.dir={run_dir}"])
    time.sleep(delay_s)
    process.send_signal(signum)
    out, err = process.communicate(timeout=300)
    result = subprocess.CompletedProcess(process.args, process.returncode, out, err)
    name = signal.Signals(signum).name
    line = assert_refused(result, 128 + signum, name)
    assert line.startswith(("interrupted", "terminated", "stopped")), line
    assert not (run_dir / "run.lock").exists()
