"""The object trajectory turns about the configured axis at the configured speed."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.sim.trajectory import ObjectTrajectory


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
