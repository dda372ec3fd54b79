"""The object trajectory turns about the configured axis at the configured speed."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.geometry import rotation_matrix
from neuralfeels_sem.sim.trajectory import ObjectTrajectory, RestHeight


@pytest.mark.parametrize("axis", [(0.0, 0.0, 1.0), (1.0, 1.0, 0.0)])
def test_rotation_without_wobble_is_exact(axis) -> None:
    centre = np.array([0.1, 0.2, 0.3])
    traj = ObjectTrajectory(centre, axis, speed_deg_s=30.0, wobble_deg=0.0, sway_m=0.0)
    a = np.asarray(axis) / np.linalg.norm(axis)
    for t in (0.0, 1.0, 2.5):
        pose = traj.pose(t)
        rot = pose[:3, :3]
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(pose[:3, 3], centre)
        np.testing.assert_allclose(rot @ a, a, atol=1e-12)  # the axis is fixed
        angle = np.degrees(np.arccos(np.clip((np.trace(rot) - 1) / 2, -1, 1)))
        assert angle == pytest.approx(30.0 * t, abs=1e-6)


def test_wobble_stays_small_and_is_seeded() -> None:
    traj = ObjectTrajectory(np.zeros(3), (0, 0, 1), speed_deg_s=30.0, wobble_deg=4.0, seed=1)
    for t in np.linspace(0, 10, 21):
        z = traj.pose(t)[:3, :3] @ np.array([0.0, 0.0, 1.0])
        tilt = np.degrees(np.arccos(np.clip(z[2], -1, 1)))
        assert tilt < 4.0 * np.sqrt(2) + 1e-6
        assert np.linalg.norm(traj.pose(t)[:3, 3]) <= 0.001 + 1e-12
    again = ObjectTrajectory(np.zeros(3), (0, 0, 1), speed_deg_s=30.0, wobble_deg=4.0, seed=1)
    np.testing.assert_allclose(traj.pose(3.3), again.pose(3.3))


def test_bad_axis_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="axis"):
        ObjectTrajectory(np.zeros(3), (0.0, 0.0, 0.0))


def _angle_deg(rot: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(rot) - 1) / 2, -1, 1))))


def test_alternate_axis_turns_about_each_axis_in_turn_and_is_continuous() -> None:
    z, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    traj = ObjectTrajectory(
        np.zeros(3),
        z,
        speed_deg_s=30.0,
        wobble_deg=0.0,
        sway_m=0.0,
        alternate_axis=x,
        alternate_every_s=2.0,
    )
    rot = lambda t: traj.pose(t)[:3, :3]  # noqa: E731
    # 0-2 s about z, 2-4 s about x, 4-6 s about z again: each stretch turns 60 degrees
    # about its own axis, whatever came before
    for start, axis in ((0.0, z), (2.0, x), (4.0, z)):
        step = rot(start + 1.5) @ rot(start).T
        np.testing.assert_allclose(step @ axis, axis, atol=1e-12)
        assert _angle_deg(step) == pytest.approx(45.0, abs=1e-6)
    # no jump at a switch
    for switch in (2.0, 4.0):
        assert _angle_deg(rot(switch + 1e-6) @ rot(switch - 1e-6).T) < 1e-3
    # the second stretch turns the object's top (z) away from the vertical
    top = rot(3.9) @ z
    assert np.degrees(np.arccos(top[2])) == pytest.approx(57.0, abs=1e-6)
    assert [traj.segment(t) for t in (0.0, 1.99, 2.0, 5.0)] == [0, 0, 1, 2]


def test_one_axis_is_unchanged_by_the_alternation_defaults() -> None:
    a = ObjectTrajectory(np.zeros(3), (0, 0, 1), wobble_deg=4.0, seed=3)
    b = ObjectTrajectory(np.zeros(3), (0, 0, 1), wobble_deg=4.0, seed=3, alternate_every_s=0.5)
    for t in (0.0, 3.0, 9.7):
        np.testing.assert_allclose(a.pose(t), b.pose(t))
    assert a.segment(100.0) == 0


def test_bad_alternate_axis_or_period_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="alternate_axis"):
        ObjectTrajectory(np.zeros(3), (0, 0, 1), alternate_axis=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="alternate_every_s"):
        ObjectTrajectory(np.zeros(3), (0, 0, 1), alternate_axis=(1, 0, 0), alternate_every_s=0.0)


def test_rest_height_lifts_a_bar_only_as_far_as_its_orientation_needs() -> None:
    """A 20 x 4 x 4 cm bar along y, 3 cm of room below the centre: flat it needs none, stood
    on end 10 cm (7 cm of lift), at 30 degrees 10 sin 30 + 2 cos 30 cm."""
    corners = np.array(
        [[x, y, z] for x in (-0.02, 0.02) for y in (-0.1, 0.1) for z in (-0.02, 0.02)]
    )
    rest = RestHeight(corners, np.array([0.0, 0.0, 2.0]), room=0.03)
    assert rest.lift(np.eye(3)) == 0.0
    x = np.array([1.0, 0.0, 0.0])
    assert rest.lift(rotation_matrix(x, np.pi / 2)) == pytest.approx(0.07)
    tilted = 0.1 * np.sin(np.pi / 6) + 0.02 * np.cos(np.pi / 6) - 0.03
    assert rest.lift(rotation_matrix(x, np.pi / 6)) == pytest.approx(tilted)
    with pytest.raises(ValueError, match="at least one"):
        RestHeight(np.zeros((0, 3)), np.array([0.0, 0.0, 1.0]), 0.0)


def test_the_pose_and_its_previews_carry_the_rest_lift() -> None:
    """Turning the bar about x stands it up: the centre rises by the lift, in pose(t), in
    steady_poses and in turn_poses alike."""
    corners = np.array(
        [[x, y, z] for x in (-0.02, 0.02) for y in (-0.1, 0.1) for z in (-0.02, 0.02)]
    )
    up = np.array([0.0, 0.0, 1.0])
    rest = RestHeight(corners, up, room=0.03)
    centre = np.array([0.0, 0.0, 0.3])
    traj = ObjectTrajectory(centre, (1, 0, 0), 30.0, wobble_deg=0.0, sway_m=0.0, rest=rest)
    for t in (0.0, 1.0, 3.0):
        pose = traj.pose(t)
        np.testing.assert_allclose(pose[:3, 3], centre + rest.lift(pose[:3, :3]) * up)
        np.testing.assert_allclose(traj.steady_poses(np.array([t]))[0], pose, atol=1e-12)
    assert traj.pose(3.0)[2, 3] == pytest.approx(0.37)  # on end after 90 degrees
    ahead = traj.turn_poses(0.0, np.array([1.0, 0.0, 0.0]), np.array([3.0]))[0]
    np.testing.assert_allclose(ahead, traj.pose(3.0), atol=1e-12)
