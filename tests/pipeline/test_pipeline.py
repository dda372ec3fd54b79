"""The producer / mapper pipeline behind task=map: offline maps every frame exactly as a
sequential loop does; realtime keeps up with the sensor's clock; a failing producer ends
the run with its error and keeps what was mapped."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra.utils import instantiate

from neuralfeels_sem.configs import to_config
from neuralfeels_sem.core.errors import DataError, FrameSourceError
from neuralfeels_sem.mapping.pose_source import build_pose_source
from neuralfeels_sem.mapping.pose_tracker import TrackerConfig
from neuralfeels_sem.pipeline.touch_advisor import TouchAdvisorConfig, touch_advisors
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.tasks.build import BOUND_MARGIN, build_mapper, build_scorer
from neuralfeels_sem.tasks.map import map_object
from neuralfeels_sem.utils.device import resolve_device
from neuralfeels_sem.utils.seed import seed_everything
from tests.helpers import TOY_MAPPING, compose_config

SMALL = [
    "object=patched_toy",
    "sensor.rgbd.width=96",
    "sensor.rgbd.height=72",
    "sensor.duration_s=1.2",
    "sensor.fps=5",
    *TOY_MAPPING,
    "mapping.mapper.warmup_steps=40",
    "classifier=oracle",
]
SAME_FIGURES = (
    "matching_curve",
    "matching_mean_class_curve",
    "matching_pct",
    "matching_mean_class_pct",
    "fscore_5mm",
    "chamfer_mm",
    "classifier_accuracy",
    "trained_on",
)
SAME_PERCEPTION = (
    "camera_frames_segmented",
    "camera_mask_iou",
    "tactile_contact_iou",
    "tactile_depth_mae_mm",
)


def _map(cfg, out: Path, wrap=None, observers=(), own_process=False) -> dict:
    """map_object on a fresh sensor (wrapped by `wrap`; in a process of its own with
    `own_process`), seeded like run.py seeds a run."""
    seed_everything(int(cfg.seed))
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, list(cfg.materials), own_process)
    sensor.open()
    try:
        return map_object(cfg, obj, wrap(sensor) if wrap else sensor, out, observers=observers)
    finally:
        sensor.close()


def _sequential_reference(cfg) -> dict:
    """The loop before the pipeline, frame by frame in one thread: classify, log, pose, add,
    score every k frames and on the last; then the final figures."""
    seed_everything(int(cfg.seed))
    obj = instantiate(cfg.object)
    sensor = build_sensor(cfg.sensor, obj, list(cfg.materials))
    sensor.open()
    try:
        classifier = instantiate(cfg.classifier)
        bound = BOUND_MARGIN * obj.bounds_radius
        mapper = build_mapper(cfg, bound, resolve_device(cfg.device), sensor.hand_model())
        scorer = build_scorer(cfg, obj)
        tracker = to_config(TrackerConfig, cfg.mapping.tracker)
        pose_source = build_pose_source(cfg.mapping.pose, obj, tracker)
        baseline, _ = scorer.field_metrics(mapper.field, bound)
        every, total = int(cfg.eval.every_k_frames), len(sensor)
        for frame in sensor.frames():
            readings = list(frame.tactile.values())
            labels = dict(zip(frame.tactile, classifier.classify(readings)))
            scorer.log_touches(frame, labels)
            pose = pose_source.estimate(frame, mapper)
            mapper.add_frame(frame, labels, world_T_object=pose)
            if frame.index % every == 0 or frame.index == total - 1:
                scorer.score(mapper.field, frame.index, frame.time_s, None)
        scores, _ = scorer.final_metrics(mapper.field, bound, baseline, None)
        return {
            **scores,
            "trained_on": mapper.trained_on,
            "perception": mapper.points.perception_summary(),
        }
    finally:
        sensor.close()


# The one-thread variants run in `make test-all` (slow): the acquisition thread is the
# default, and tests/pipeline/test_producer.py covers both hand-overs quickly.
ACQUIRE = pytest.mark.parametrize(
    "acquire",
    [True, pytest.param(False, marks=pytest.mark.slow)],
    ids=["acquire-thread", "one-thread"],
)


@pytest.mark.parametrize(
    "acquire, own_process",
    [
        (True, True),
        # the other tests here map with the sensor in the test's process
        pytest.param(True, False, marks=pytest.mark.slow),
        pytest.param(False, False, marks=pytest.mark.slow),
    ],
    ids=["acquire-process", "acquire-thread", "one-thread"],
)
def test_offline_pipeline_gives_the_sequential_loops_figures(
    tmp_path, acquire, own_process
) -> None:
    # With acquisition in a thread of its own, the sensor in a process of its own or not:
    # the same frames, labels and figures.
    cfg = compose_config([*SMALL, f"mapping.acquire_thread={acquire}"])
    metrics = _map(cfg, tmp_path, own_process=own_process)
    expected = json.loads(json.dumps(_sequential_reference(cfg), default=float))
    got = json.loads((tmp_path / "metrics.json").read_text())
    assert got["pace"] == "offline" and got["frames_dropped"] == 0
    assert got["lag_max_s"] is None and got["idle_steps"] == 0
    assert metrics["frames"] == 6 and got["trained_on"]["frames"] == 6
    # Each side's CPU time: some, and no more than the loop's wall time per thread (the
    # producer's threads start with the loop and are joined at its end).
    threads = {"producer_cpu_s": 2 if acquire else 1, "mapper_cpu_s": 1}
    for key, n in threads.items():
        assert 0.0 < got[key] <= n * got["wall_s"] + 0.5, (key, got[key], got["wall_s"])
    # The producer's time by stage: each stage some, together within the producer's threads.
    stages = got["producer_stage_cpu_s"]
    child = stages.pop("acquire_process", None)  # the sensor's own process
    assert (child is not None and child > 0.0) == own_process, child
    assert sorted(stages) == ["acquire", "classify", "perceive"]
    assert all(seconds > 0.0 for seconds in stages.values()), stages
    assert sum(stages.values()) <= got["producer_cpu_s"] + 1e-3
    for key in SAME_PERCEPTION:  # segmentation_ms_mean is a timing
        assert got["perception"][key] == expected["perception"][key], key
    for key in SAME_FIGURES:
        assert got[key] == expected[key], key
    # the figures compared are not those of an empty map
    assert got["matching_mean_class_pct"] > 0 and got["trained_on"]["labelled_touches"] > 0


@ACQUIRE
def test_realtime_keeps_within_the_lag_bound_and_counts_its_drops(tmp_path, acquire) -> None:
    # 10 fps of sensor time on a toy mapper that cannot keep up under test load.
    pace = ["sensor.fps=10", "sensor.pace=realtime", "mapping.max_lag_s=2.0"]
    # with two producer threads, the touches of overtaken frames are kept too
    touches = f"mapping.overtaken_touch_frames={4 if acquire else 0}"
    cfg = compose_config([*SMALL, *pace, f"mapping.acquire_thread={acquire}", touches])
    metrics = _map(cfg, tmp_path)
    got = json.loads((tmp_path / "metrics.json").read_text())
    assert got["pace"] == "realtime" and got["max_lag_s"] == 2.0
    assert got["frames"] >= 1 and got["frames"] + got["frames_dropped"] == 12
    assert 0.0 <= got["lag_mean_s"] <= got["lag_max_s"] <= 2.0
    assert got["trained_on"]["frames"] == got["frames"]
    logged = {int(line.split(",")[0]) for line in _touch_rows(tmp_path)}
    # touches are logged for the frames mapped and those whose touches alone were
    assert logged <= set(range(12)) and len(logged) <= got["frames"] + got["touch_frames"]
    assert got["touch_frames"] <= got["frames_dropped"] and (acquire or got["touch_frames"] == 0)
    assert got["matching_curve"][-1][0] == metrics["frames_total"] - 1 or got["frames"] == 12
    assert np.isfinite(got["matching_mean_class_pct"])


def _touch_rows(run_dir: Path) -> list[str]:
    return [r for r in (run_dir / "touches.csv").read_text().splitlines()[1:] if r]


class _FailingSensor:
    """Wraps a sensor; its frames raise `error` when frame `at` is due."""

    def __init__(self, sensor, at: int, error: BaseException) -> None:
        self._sensor, self.at, self.error = sensor, at, error

    def __getattr__(self, name):
        return getattr(self._sensor, name)

    def __len__(self) -> int:
        return len(self._sensor)

    def frames(self):
        for frame in self._sensor.frames():
            if frame.index == self.at:
                raise self.error
            yield frame


@pytest.mark.parametrize(
    "error, raised, acquire",
    [(RuntimeError("renderer lost its context\nsecond line"), FrameSourceError, True),
     pytest.param(RuntimeError("renderer lost its context\nsecond line"), FrameSourceError, False,
                  marks=pytest.mark.slow),
     (DataError("frame 3: frames.jsonl is damaged"), DataError, True)],
    ids=["crash-in-acquire-thread", "crash-one-thread", "user-error"],
)  # fmt: skip
def test_a_failing_producer_ends_the_run_and_keeps_what_was_mapped(
    tmp_path, error, raised, acquire
) -> None:
    cfg = compose_config([*SMALL, f"mapping.acquire_thread={acquire}"])
    with pytest.raises(raised) as caught:
        _map(cfg, tmp_path, wrap=lambda s: _FailingSensor(s, 3, error))
    message = str(caught.value)
    assert "\n" not in message
    if raised is FrameSourceError:
        assert "renderer lost its context" in message and "after frame 2" in message
        assert f"mapping.resume={tmp_path / 'checkpoint.pt'}" in message
    checkpoint = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert checkpoint["frame_index"] == 2
    got = json.loads((tmp_path / "metrics.json").read_text())
    assert got["partial"] is True and got["stopped_by"] == "error"
    assert got["frames"] == 3 and got["error"].startswith(type(error).__name__)
    assert (tmp_path / "touches.csv").read_text().startswith("# partial")


def test_a_producer_failing_before_any_data_raises_its_error_alone(tmp_path) -> None:
    cfg = compose_config(SMALL)
    with pytest.raises(RuntimeError, match="no frames today"):
        _map(cfg, tmp_path, wrap=lambda s: _FailingSensor(s, 0, RuntimeError("no frames today")))
    assert not (tmp_path / "metrics.json").exists()


@pytest.mark.slow  # 30 s; test_process_sensor.py checks the same hand-over in seconds
@pytest.mark.timeout(300)  # the deadlock this guards against waited 600 s for advice
def test_active_touch_with_the_simulator_in_its_own_process(tmp_path) -> None:
    """The advisor hands the sensor its advice and reads its plan on the mapper's thread
    while the child makes the next frame, which waits for that advice: the run must end
    with the figures of the same run with the sensor in the test's process."""
    cfg = compose_config([*SMALL, "sensor.policy=active"])
    got = {}
    for own_process in (True, False):
        out = tmp_path / str(own_process)
        out.mkdir()
        seed_everything(int(cfg.seed))
        obj = instantiate(cfg.object)
        sensor = build_sensor(cfg.sensor, obj, list(cfg.materials), own_process)
        sensor.open()
        try:
            advisors = touch_advisors(to_config(TouchAdvisorConfig, cfg.mapping.advisor),
                                      sensor, out)  # fmt: skip
            assert len(advisors) == 1
            got[own_process] = map_object(cfg, obj, sensor, out, observers=advisors)
        finally:
            sensor.close()
    for key in SAME_FIGURES:
        assert got[True][key] == got[False][key], key
    suggestions = json.loads((tmp_path / "True" / "touch_suggestions.json").read_text())
    plan = suggestions["touch_plan"]
    assert plan["policy"] == "active" and plan["choices"] > 0
