"""The sliding window of tracked poses (`mapping.tracker.window`, pose_window.py): the joint
solve, its motion residuals, re-placing refined frames in the map, resume and settings."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.geometry import invert_pose, transform_points
from neuralfeels_sem.mapping.keyframes import KeyframeBuffer
from neuralfeels_sem.mapping.known_shape import GridSdf
from neuralfeels_sem.mapping.pose_error import average_3d_error
from neuralfeels_sem.mapping.pose_source import TrackedPose
from neuralfeels_sem.mapping.pose_tracker import PoseTracker, TrackerConfig, se3_exp
from neuralfeels_sem.mapping.pose_window import PoseWindow, WindowConfig
from neuralfeels_sem.mapping.touch_memory import TouchBuffer
from tests.mapping.test_pose_source import FakeMapper, egg, frame_at, trajectory


@pytest.fixture(scope="module")
def obj():
    return egg()


@pytest.fixture(scope="module")
def egg_sdf(obj):
    return GridSdf.of_mesh(obj.mesh, 48)


def window(frames: int = 4, motion_weight: float = 0.01, rotation_scale: float = 0.03):
    tracker = PoseTracker(TrackerConfig(rotation_scale=rotation_scale, seed=0))
    config = WindowConfig(frames=frames, motion_weight=motion_weight)
    return PoseWindow(config, tracker)


def nudge(pose: np.ndarray, k: int) -> np.ndarray:
    """`pose` moved by about a millimetre and a degree, differently for each k."""
    rng = np.random.default_rng(k)
    return pose @ se3_exp(np.concatenate([rng.normal(0, 6e-4, 3), rng.normal(0, 0.012, 3)]))


def test_joint_solve_pulls_every_frame_of_the_window_back(obj, egg_sdf) -> None:
    """Each frame's own points pin its pose (an egg with a bump): poses handed in a
    millimetre off end on the true ones, the earlier frames through their corrections."""
    win, mapper, poses = window(), FakeMapper(obj), trajectory(7)
    placed = {}  # frame -> the pose its points sit at in the map
    for k, truth in enumerate(poses):
        given = nudge(truth, k)
        placed[k] = given
        pose, moves = win.refine(
            k, given, mapper.frame_points(frame_at(k, truth), np.eye(4)), egg_sdf
        )
        for index, move in moves.items():
            assert index < k
            placed[index] = placed[index] @ invert_pose(move)  # the map's points follow
        placed[k] = pose
        assert k == 0 or average_3d_error(pose, truth, obj.mesh.vertices) < average_3d_error(
            given, truth, obj.mesh.vertices
        )
    for k in range(len(poses) - 3, len(poses)):
        assert average_3d_error(placed[k], poses[k], obj.mesh.vertices) < 1e-4
    assert win.solves == len(poses) - 1 and win.rejected == 0 and len(win.frames) == 3


def test_motion_residuals_hold_a_spin_the_points_cannot_see() -> None:
    """A sphere's spin moves no point off its surface: the window's constant-velocity
    residuals bring a wrong spin of the newest frame back to the motion of those before."""
    sphere = lambda x: x.norm(dim=1) - 0.03  # noqa: E731
    rng = np.random.default_rng(0)
    unit = rng.normal(size=(800, 3))
    surface = 0.03 * unit / np.linalg.norm(unit, axis=1, keepdims=True)
    win = window(frames=4, motion_weight=1.0)
    turn = se3_exp(np.array([0.001, 0, 0, 0, 0, np.deg2rad(3.0)]))
    poses = [np.eye(4)]
    for _ in range(4):
        poses.append(poses[-1] @ turn)
    for k, truth in enumerate(poses):
        points = {"camera": transform_points(truth, surface)}
        given = truth @ se3_exp(np.array([0, 0, 0, 0, 0, np.deg2rad(2.0)])) if k == 4 else truth
        pose, _ = win.refine(k, given, points, sphere)
    spin = np.rad2deg(np.arccos(np.clip((np.trace(invert_pose(poses[-1]) @ pose) - 2) / 2, -1, 1)))
    assert spin < 0.2


def test_a_resumed_window_starts_again_and_counts_on(obj, egg_sdf) -> None:
    """Colour rows of past frames are not kept, so resume restarts the window: the next
    frame is not solved jointly, the one after it is, and the counts carry over."""
    mapper, poses = FakeMapper(obj), trajectory(6)
    points = [mapper.frame_points(frame_at(k, p), np.eye(4)) for k, p in enumerate(poses)]
    first, resumed = window(), window()
    for k in range(4):
        first.refine(k, nudge(poses[k], k), points[k], egg_sdf)
    resumed.load_state(first.state())
    assert resumed.metrics() == first.metrics() and not resumed.frames
    _, moves = resumed.refine(4, nudge(poses[4], 4), points[4], egg_sdf)
    assert moves == {} and resumed.solves == first.solves
    _, moves = resumed.refine(5, nudge(poses[5], 5), points[5], egg_sdf)
    assert list(moves) == [4] and resumed.solves == first.solves + 1


def test_settings_out_of_range_are_one_line_errors() -> None:
    with pytest.raises(ValueError, match="window needs frames >= 0"):
        WindowConfig(frames=-1)
    with pytest.raises(ValueError, match="points_per_frame"):
        WindowConfig(points_per_frame=2)
    with pytest.raises(ValueError, match="motion_weight"):
        WindowConfig(motion_weight=-1.0)
    assert not PoseWindow(WindowConfig(frames=1), PoseTracker()).enabled


def test_a_refined_frame_is_re_placed_in_the_map() -> None:
    """Keyframes and touches of the moved frame turn and shift; other frames stay."""
    move = se3_exp(np.array([0.002, 0, 0, 0, 0, 0.1]))
    rotation = torch.as_tensor(move[:3, :3], dtype=torch.float32)
    shift = torch.as_tensor(move[:3, 3], dtype=torch.float32)
    keyframes = KeyframeBuffer(max_keyframes=10, window_recent=2, window_by_loss=0)
    touches = TouchBuffer(torch.device("cpu"))
    points = torch.rand(5, 3)
    for index in (4, 5):
        keyframes.add(points.clone(), torch.zeros(3), frame_index=index)
        touches.add(points.clone(), torch.tensor([0.0, 0.0, 1.0]), 1, 1.0, "index", index)
    before = touches.tensors()["points"].clone()
    assert keyframes.move_frame(5, rotation, shift) == 1
    assert touches.move_frame(5, rotation, shift) == 1
    expected = points @ rotation.T + shift
    torch.testing.assert_close(keyframes.points[1], expected)
    torch.testing.assert_close(keyframes.points[0], points)
    torch.testing.assert_close(keyframes.origins[1], shift)
    after = touches.tensors()
    torch.testing.assert_close(after["points"][:5], before[:5])
    torch.testing.assert_close(after["points"][5:], expected)
    torch.testing.assert_close(after["axes"][5], rotation[:, 2])


class MovingMapper(FakeMapper):
    """FakeMapper that records which frames the pose source re-places."""

    def __init__(self, obj, sdf) -> None:
        super().__init__(obj, sdf=sdf)
        self.moved: list[int] = []

    def move_frame(self, frame_index: int, object_T_object: np.ndarray) -> int:
        self.moved.append(frame_index)
        return 1


def test_tracked_pose_with_a_window_re_places_earlier_frames(obj, egg_sdf) -> None:
    config = TrackerConfig(rotation_scale=0.03, window=WindowConfig(frames=3))
    source = TrackedPose("track", obj, PoseTracker(config))
    mapper = MovingMapper(obj, egg_sdf)
    for k, truth in enumerate(trajectory(6)):
        source.estimate(frame_at(k, truth), mapper)
    metrics = source.metrics()
    # frame 0 is the map's origin; frame 1 starts the window (nothing to solve jointly yet)
    assert metrics["pose_frames_tracked"] == 5 and metrics["pose_window_solves"] == 4
    assert mapper.moved and max(mapper.moved) <= 4
    assert metrics["pose_error_max_mm"] < 0.5


def test_the_motion_prior_takes_the_refined_pose_of_the_previous_frame(obj, egg_sdf) -> None:
    """With frames skipped (realtime pacing maps every other frame here), the previous
    frame is not index - 1: the motion prior must still take its refined pose."""
    config = TrackerConfig(rotation_scale=0.03, window=WindowConfig(frames=3))
    source = TrackedPose("track", obj, PoseTracker(config))
    mapper = MovingMapper(obj, egg_sdf)
    for k, truth in enumerate(trajectory(12)):
        if k % 2 == 0:
            source.estimate(frame_at(k, truth), mapper)
    assert mapper.moved and all(index % 2 == 0 for index in mapper.moved)
    np.testing.assert_allclose(source.history[-2], source.window.frames[-2].pose, atol=1e-12)
