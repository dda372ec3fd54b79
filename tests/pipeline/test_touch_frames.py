"""The touches of overtaken frames at sensor.pace=realtime: the producer keeps those with
a contact for the next frame; the session maps them before it, each with its own pose
(mapping.pose=gt) or one interpolated between the mapped frames around it (tracked)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.mapping.se3 import interpolate_pose, se3_exp
from neuralfeels_sem.pipeline.pace import PerceivedFrame, StreamEnd
from neuralfeels_sem.pipeline.producer import FrameProducer
from neuralfeels_sem.pipeline.touch_frames import OvertakenTouches


def _pose(x: float, angle: float) -> np.ndarray:
    return se3_exp(np.array([x, 0.0, 0.0, 0.0, 0.0, angle]))


def _frame(index: int, pose: np.ndarray | None = None) -> Frame:
    return Frame(index, index * 0.1, np.eye(4) if pose is None else pose)


def test_interpolated_pose_runs_the_constant_motion_between_the_ends() -> None:
    start, end = _pose(0.0, 0.0), _pose(0.02, 0.4)
    np.testing.assert_allclose(interpolate_pose(start, end, 0.0), start, atol=1e-12)
    np.testing.assert_allclose(interpolate_pose(start, end, 1.0), end, atol=1e-12)
    half = interpolate_pose(start, end, 0.5)
    np.testing.assert_allclose(half @ half, end, atol=1e-12)  # two equal steps from identity
    with pytest.raises(ValueError, match="share=1.5 must be in"):
        interpolate_pose(start, end, 1.5)


class _Listener:
    """An observer with the optional on_touches hook."""

    def __init__(self) -> None:
        self.heard = []

    def on_touches(self, frame, labels, world_T_object, mapper) -> None:
        self.heard.append((frame.index, world_T_object))


class _Session:
    """What OvertakenTouches reads of a MappingSession: scorer, pose source, mapper,
    observers (one with on_touches, one without)."""

    def __init__(self, source: str) -> None:
        self.logged, self.added = [], []
        self.listener = _Listener()
        self.observers = [SimpleNamespace(on_frame=None), self.listener]
        self.scorer = SimpleNamespace(log_touches=lambda f, labels: self.logged.append(f.index))
        self.pose_source = SimpleNamespace(reads_frame_pose=source == "gt")
        self.mapper = SimpleNamespace(
            add_touches=lambda f, labels, pose, depths: self.added.append((f.index, pose, depths))
        )


class _Points:
    def __init__(self) -> None:
        self.read = []

    def contact_depths(self, frame: Frame) -> dict:
        self.read.append(frame.index)
        return {"index": frame.index}


def _labels(touched: bool) -> dict:
    return {"index": SimpleNamespace(contact=touched)}


def test_gt_places_each_touch_with_its_own_pose() -> None:
    overtaken, session, points = OvertakenTouches(True), _Session("gt"), _Points()
    touch = _frame(3, _pose(0.01, 0.1))
    riding = overtaken.take(points, [(touch, _labels(True))])
    assert overtaken.add(session, riding, _frame(4), _pose(0.5, 0.0)) == 1
    assert session.logged == [3] and points.read == [3]
    index, pose, depths = session.added[0]
    assert index == 3 and depths == {"index": 3}
    np.testing.assert_array_equal(pose, touch.world_T_object)
    # observers with the hook hear of the mapped touches, at the pose they were mapped at
    assert [i for i, _ in session.listener.heard] == [3]
    np.testing.assert_array_equal(session.listener.heard[0][1], touch.world_T_object)


def test_tracked_touches_take_the_pose_interpolated_in_time() -> None:
    """Mapped frames 2 (pose A) and 6 (pose B): a touch of frame 3 takes the pose a
    quarter of the way; the frame's own pose (here the truth) is never read."""
    overtaken, session, points = OvertakenTouches(True), _Session("track"), _Points()
    start, end = _pose(0.0, 0.0), _pose(0.04, 0.8)
    overtaken.add(session, [], _frame(2), start)
    riding = overtaken.take(points, [(_frame(3, _pose(9.0, 0.0)), _labels(True))])
    overtaken.add(session, riding, _frame(6), end)
    np.testing.assert_allclose(session.added[0][1], interpolate_pose(start, end, 0.25))


def test_a_frame_dropped_for_its_lag_carries_its_touches_to_the_next() -> None:
    overtaken, session, points = OvertakenTouches(True), _Session("gt"), _Points()
    late = PerceivedFrame(_frame(2), _labels(True), touches=[(_frame(1), _labels(True))])
    assert overtaken.carry(late) is True
    assert overtaken.carry(PerceivedFrame(_frame(3), _labels(False))) is False
    riding = overtaken.take(points, [(_frame(4), _labels(True))])
    overtaken.add(session, riding, _frame(5), np.eye(4))
    assert [a[0] for a in session.added] == [1, 2, 4] and points.read == [1, 2, 4]
    assert OvertakenTouches(False).carry(late) is False


class _Realtime:
    """A realtime sensor: frame 0, then touches-only frames 1-3 (1 and 3 touching), then 4."""

    pace = "realtime"
    frame_period_s = 0.01

    def __len__(self) -> int:
        return 5

    def frames_from_clock(self, due_index, touch_frames=0):
        assert touch_frames == 3
        due_index()
        for index, only in [(0, False), (1, True), (2, True), (3, True), (4, False)]:
            reading = SimpleNamespace(finger="index", at=index)
            yield SimpleNamespace(index=index, tactile={"index": reading}, touches_only=only)


def test_the_producer_sends_the_touching_overtaken_frames_with_the_next() -> None:
    perceived = []
    producer = FrameProducer(
        _Realtime(),
        classify=lambda readings: [SimpleNamespace(contact=r.at != 2) for r in readings],
        perceive=lambda frame: perceived.append(frame.index),
        forget=lambda frame: None,
        touch_frames=3,
    )
    producer.start()
    items = []
    while not isinstance(item := producer.queue.get(timeout=5.0), StreamEnd):
        assert item is not None, "the producer stalled"
        items.append(item)
    producer.stop()
    assert [i.frame.index for i in items] == [0, 4]
    assert [f.index for f, _ in items[1].touches] == [1, 3]
    assert perceived == [0, 1, 3, 4]  # the overtaken frame 2 had no contact: not perceived
