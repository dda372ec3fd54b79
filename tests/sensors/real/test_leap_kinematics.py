"""LEAP Hand kinematics against the chained joint origins of its public URDF, computed here independently."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from neuralfeels_sem.sensors.real.leap_kinematics import PALM_ORIGIN_URDF, LeapKinematics

# leap-hand/LEAP_Hand_Sim assets/leap_hand/robot.urdf: joint name -> (origin xyz, origin rpy),
# at the file's precision (10 significant digits), every axis 0 0 -1.
URDF_JOINTS = {
    "1": ((-0.007095249653, 0.02305775613, -0.01872240358), (1.570796327, 1.570796327, 0.0)),
    "5": ((-0.007095249653, -0.02239224387, -0.01872240358), (1.570796327, 1.570796327, 0.0)),
    "9": ((-0.007095245443, -0.06784224387, -0.01872240767), (1.570796327, 1.570796327, 0.0)),
    "0": ((-0.0122, 0.0381, 0.0145), (-1.570796327, -1.006521266e-15, 1.570796327)),
    "2": ((0.015, 0.0143, -0.013), (1.570796327, -1.570796327, 0.0)),
    "3": ((-4.08805825e-09, -0.03610000421, 0.0002), (4.59e-17, -2.87e-16, 0.0)),
    "12": ((-0.06939524965, -0.001242243865, -0.02162240358), (-8.24e-17, 1.570796327, 0.0)),
    "13": ((-2.78e-17, 0.0143, -0.013), (1.570796327, -1.570796327, 0.0)),
    "14": ((0.0, 0.0145, -0.017), (-1.570796327, 0.0, 0.0)),
    "15": ((-1.249e-16, 0.0466, 0.0002), (0.0, 5.42e-31, 3.141592654)),
}
# Chains from palm_lower to each distal link, as (URDF joint, index into q). The side-to-side
# joint "0" sits after the forward joint "1" on every finger; fingers 2 and 3 repeat the
# index finger's links with their own base joint.
CHAINS = {
    "index": [("1", 1), ("0", 0), ("2", 2), ("3", 3)],
    "middle": [("5", 5), ("0", 4), ("2", 6), ("3", 7)],
    "ring": [("9", 9), ("0", 8), ("2", 10), ("3", 11)],
    "thumb": [("12", 12), ("13", 13), ("14", 14), ("15", 15)],
}
URDF_LOWER = [-1.047, -0.314, -0.506, -0.366] * 3 + [-0.349, -0.47, -1.20, -1.34]
URDF_UPPER = [1.047, 2.23, 1.885, 2.042] * 3 + [2.094, 2.443, 1.90, 1.88]


def urdf_chain(finger: str, q: np.ndarray) -> np.ndarray:
    """palm_lower_T_distal from the URDF numbers (scipy's extrinsic xyz = URDF rpy)."""
    pose = np.eye(4)
    for joint, index in CHAINS[finger]:
        xyz, rpy = URDF_JOINTS[joint]
        origin = np.eye(4)
        origin[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
        origin[:3, 3] = xyz
        motion = np.eye(4)
        motion[:3, :3] = Rotation.from_rotvec(-q[index] * np.array([0.0, 0.0, 1.0])).as_matrix()
        pose = pose @ origin @ motion
    return pose


def palm_T_urdf() -> np.ndarray:
    """Documented palm frame: fingers +z (URDF +x), palm normal +x (URDF -z), index +y (URDF +y)."""
    rot = np.stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = -rot @ np.asarray(PALM_ORIGIN_URDF)
    return pose


WORLD_T_PALM = np.array(
    [[0.0, 0.0, 1.0, -0.05], [0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.15], [0, 0, 0, 1.0]]
)


@pytest.mark.parametrize("seed", [None, 0, 1])
def test_fingertips_follow_the_urdf_chain(seed: int | None) -> None:
    kin = LeapKinematics(world_T_palm=WORLD_T_PALM)
    lower, upper = np.array(URDF_LOWER), np.array(URDF_UPPER)
    q = np.zeros(16) if seed is None else np.random.default_rng(seed).uniform(lower, upper)
    got = kin.fingertip_poses(q)
    for finger in CHAINS:
        expected = WORLD_T_PALM @ palm_T_urdf() @ urdf_chain(finger, q)
        np.testing.assert_allclose(got[finger][:3, 3], expected[:3, 3], atol=3e-6)
        np.testing.assert_allclose(got[finger][:3, :3], expected[:3, :3], atol=1e-9)


def test_zero_pose_fingertips_match_the_summed_urdf_origins() -> None:
    # At q = 0 the fingers are straight: the chain of origins alone fixes the tips, in metres
    # from palm_lower (values read off the URDF chain, rounded to 0.1 mm).
    kin = LeapKinematics(world_T_palm=np.linalg.inv(palm_T_urdf()))  # report in palm_lower
    tips = {f: p[:3, 3] for f, p in kin.fingertip_poses(np.zeros(16)).items()}
    np.testing.assert_allclose(tips["index"], [0.0821, 0.0227, -0.0195], atol=1e-4)
    np.testing.assert_allclose(tips["middle"], [0.0821, -0.0228, -0.0195], atol=1e-4)
    np.testing.assert_allclose(tips["ring"], [0.0821, -0.0682, -0.0195], atol=1e-4)
    np.testing.assert_allclose(tips["thumb"], [-0.0824, 0.0767, -0.0069], atol=1e-4)


def test_joint_limits_are_the_urdf_ones_and_clip_respects_them() -> None:
    kin = LeapKinematics()
    np.testing.assert_array_equal(kin.joint_limits[:, 0], URDF_LOWER)
    np.testing.assert_array_equal(kin.joint_limits[:, 1], URDF_UPPER)
    q = kin.clip(np.full(16, 5.0))
    np.testing.assert_array_equal(q, URDF_UPPER)
    assert kin.joint_names[:4] == ["index_mcp_side", "index_mcp_forward", "index_pip", "index_dip"]
    assert kin.joint_names[12:] == ["thumb_cmc", "thumb_axial", "thumb_mcp", "thumb_ip"]


def test_digits_look_out_of_the_pads() -> None:
    kin = LeapKinematics(world_T_palm=np.eye(4))
    poses = kin.sensor_poses(np.zeros(16))
    gels = kin.gel_centres(np.zeros(16))
    for pose in poses.values():
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)
        assert np.linalg.det(pose[:3, :3]) == pytest.approx(1.0)
    for finger in ("index", "middle", "ring"):  # straight fingers: pads face the palm normal
        np.testing.assert_allclose(poses[finger][:3, 2], [1.0, 0.0, 0.0], atol=1e-9)
        np.testing.assert_allclose(poses[finger][:3, 1], [0.0, 0.0, -1.0], atol=1e-9)
    assert gels["middle"][1] == pytest.approx(0.0, abs=1e-6)  # palm origin in its mid-plane
    assert gels["index"][1] > 0.04 > -0.04 > gels["ring"][1]  # 45.5 mm finger spacing
    # A grasp: curled fingers and an opposed thumb press their pads toward each other.
    q = np.zeros(16)
    for base in (0, 4, 8):
        q[base + 1 : base + 4] = (0.9, 0.6, 0.3)
    q[12:] = (1.4, 0.0, 0.3, 0.3)
    grasp = kin.sensor_poses(q)
    gels = kin.gel_centres(q)
    gap = gels["index"] - gels["thumb"]
    assert np.dot(grasp["thumb"][:3, 2], gap) > 0 and np.dot(grasp["index"][:3, 2], gap) < 0


def test_bad_joint_vector_shape() -> None:
    with pytest.raises(ValueError, match=r"shape \(16,\)"):
        LeapKinematics().sensor_poses(np.zeros(15))
