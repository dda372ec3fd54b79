"""The live view (viz.live=rerun): refused in one line without its extra, streams a run into
live.rrd that rerun reads back, and leaves the mapping itself unchanged."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hydra.utils import instantiate

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.frame import Frame, TactileReading
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.map import map_object
from neuralfeels_sem.tasks.preflight import check_live_view
from neuralfeels_sem.utils.paths import REPO_DIR
from neuralfeels_sem.utils.seed import seed_everything
from neuralfeels_sem.viz.live import RRD_NAME, RerunLiveView, build_live_view
from tests.helpers import TOY_MAPPING, compose_config
from tests.reliability.checks import assert_refused

TINY = [
    "object=patched_toy",
    "classifier=oracle",
    "sensor.rgbd.width=96",
    "sensor.rgbd.height=72",
    "sensor.duration_s=0.8",
    "sensor.fps=5",
    *TOY_MAPPING,
    "eval.every_k_frames=2",
    "viz.live_mesh_resolution=24",
]
SAME_FIGURES = ("matching_curve", "matching_mean_class_pct", "fscore_5mm", "trained_on")


def test_the_default_run_has_no_live_view(tmp_path: Path) -> None:
    cfg = compose_config()
    assert cfg.viz.live == "none"
    assert build_live_view(cfg.viz.live, tmp_path, list(cfg.materials)) == []
    with pytest.raises(ValueError, match="rerun"):
        build_live_view("viser", tmp_path, list(cfg.materials))


def test_live_view_without_the_extra_is_one_line_naming_the_install(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)  # `import rerun` raises ImportError
    cfg = compose_config(["viz.live=rerun"])
    with pytest.raises(ConfigError) as info:
        check_live_view(cfg)
    message = str(info.value)
    assert "\n" not in message
    assert "viz.live=rerun" in message and "pip install -e .[live]" in message
    check_live_view(compose_config(["viz.live=none"]))  # nothing asked, nothing refused


def test_the_command_line_refuses_it_before_any_set_up(tmp_path: Path) -> None:
    """A `rerun` that fails to import (as where the extra is absent): exit 2, one line."""
    shadow = tmp_path / "shadow" / "rerun"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text("raise ImportError('No module named rerun')\n")
    env = dict(
        os.environ,
        PYTHONPATH=str(tmp_path / "shadow"),
        HYDRA_FULL_ERROR="0",
        TQDM_DISABLE="1",
    )
    result = subprocess.run(
        [
            sys.executable,
            str(REPO_DIR / "run.py"),
            "viz.live=rerun",
            f"hydra.run.dir={tmp_path / 'run'}",
        ],
        cwd=REPO_DIR,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert_refused(result, 2, "viz.live=rerun", "pip install -e .[live]")
    assert not (tmp_path / "run" / "checkpoint.pt").exists()


def _map(overrides: list[str], out: Path, live: bool) -> dict:
    """A toy task=map run into `out`, seeded as run.py seeds it, with or without the view."""
    cfg = compose_config([*TINY, *overrides])
    out.mkdir(parents=True)
    seed_everything(int(cfg.seed))
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, list(cfg.materials))
    sensor.open()
    kind = "rerun" if live else "none"
    observers = build_live_view(
        kind, out, list(cfg.materials), mesh_resolution=cfg.viz.live_mesh_resolution
    )
    try:
        return map_object(cfg, obj, sensor, out, observers=observers)
    finally:
        sensor.close()


class _Recording:
    """Stands in for rerun's RecordingStream: keeps what is logged."""

    def __init__(self, name: str) -> None:
        self.logged = []

    def set_sinks(self, *sinks) -> None:
        pass

    def set_time(self, *args, **kwargs) -> None:
        pass

    def log(self, path: str, value, static: bool = False) -> None:
        self.logged.append((path, value))


def test_touches_of_frames_not_mapped_join_the_touches(tmp_path: Path, monkeypatch) -> None:
    """on_touches (sensor.pace=realtime: a frame the mapper did not take) adds its
    classified touches to `world/object/touches`, and logs nothing of the camera or hand."""
    fake = SimpleNamespace(
        RecordingStream=_Recording, FileSink=str, AnnotationContext=list,
        Points3D=lambda points, **kwargs: (np.asarray(points), kwargs),
    )  # fmt: skip
    monkeypatch.setitem(sys.modules, "rerun", fake)
    view = RerunLiveView(tmp_path, ["plastic", "fabric"])
    world_T_sensor = np.eye(4)
    world_T_sensor[:3, 3] = [0.01, 0.0, 0.0]
    reading = TactileReading(
        "index", np.zeros((320, 240, 3), np.uint8), world_T_sensor, DIGIT_INTRINSICS
    )
    other = TactileReading("thumb", np.zeros((320, 240, 3), np.uint8), np.eye(4), DIGIT_INTRINSICS)
    frame = Frame(7, 0.7, np.eye(4), {"index": reading, "thumb": other})
    labels = {"index": TouchLabel("index", True, 1, 0.99), "thumb": TouchLabel("thumb", False)}
    view.on_touches(frame, labels, np.eye(4), None)
    logged = [path for path, _ in view.rec.logged]
    assert logged == ["world", "world/object/touches"]
    points, kwargs = view.rec.logged[-1][1]
    np.testing.assert_allclose(points, [[0.01, 0.0, GEL_DISTANCE_M]])
    assert list(kwargs["class_ids"]) == [1]


def test_a_map_run_streams_a_recording_rerun_reads_back(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    viewed = _map([], tmp_path / "viewed", live=True)
    plain = _map([], tmp_path / "plain", live=False)
    for key in SAME_FIGURES:  # observers read the mapper, never change it
        assert viewed[key] == plain[key], key
    assert not (tmp_path / "plain" / RRD_NAME).exists()

    path = tmp_path / "viewed" / RRD_NAME
    assert path.stat().st_size > 0
    rows: dict[str, int] = {}
    for chunk in RrdReader(path).stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
        if chunk.entity_path.startswith("/world/object"):
            assert "frame" in chunk.timeline_names
    expected = [
        "/world/camera/points",
        "/world/object",
        "/world/object/touches",
        "/world/object/map",
        "/world/object/map_uncertainty",
        "/world/hand/gel_centres",
        "/scores/matching_mean_class_pct",
        *(f"/world/hand/{finger}" for finger in FINGERS),
    ]
    for entity in expected:
        assert rows.get(entity, 0) > 0, (entity, sorted(rows))
    frames = viewed["frames"]
    assert rows["/world/object"] == frames  # one object pose per mapped frame
    assert rows["/world/object/map"] == len(viewed["matching_curve"])  # one per scoring pass
