"""Forward kinematics of the LEAP Hand (right) with a DIGIT in place of each fingertip.

Geometry from the hand's public URDF (leap-hand/LEAP_Hand_Sim, assets/leap_hand/robot.urdf,
which MuJoCo Menagerie's leap_hand also derives from): joint origins (xyz, rpy) rounded to
1 um, every joint revolute about its child frame's -z, limits as in the URDF (the same as
LEAP_Hand_API's sim limits).

Joint order = motor ids on a stock hand = the URDF's joint names "0".."15": index 0-3,
middle 4-7, ring 8-11 each [MCP side-to-side, MCP forward, PIP, DIP]; thumb 12-15
[CMC, axial, MCP, IP]. In each finger's chain the MCP *forward* joint comes first (palm ->
mcp_joint), then side-to-side, so chain order is (1, 0, 2, 3). Angles are the URDF's
(0 = flat hand); the real motors read pi there, which DynamixelHand's zero_raw=2048 removes.

Palm frame (world_T_palm) follows the project's hand convention so a config carries over
between hands: origin on the middle finger's MCP forward axis, in that finger's mid-plane;
fingers along +z, palm normal +x, index toward +y. In the URDF's palm_lower frame the fingers run along +x, the
palm faces -z and the index sits at +y.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.geometry import check_pose
from neuralfeels_sem.core.hand import FINGERS, default_world_T_palm

HALF_PI = np.pi / 2
Origin = tuple[tuple[float, float, float], tuple[float, float, float]]  # (xyz m, rpy rad)

# palm_lower -> mcp_joint (MCP forward joint): only the position differs between fingers.
FINGER_BASE_XYZ = {
    "index": (-0.007095, 0.023058, -0.018722),  # URDF joint 1
    "middle": (-0.007095, -0.022392, -0.018722),  # URDF joint 5
    "ring": (-0.007095, -0.067842, -0.018722),  # URDF joint 9
}
FINGER_BASE_RPY = (HALF_PI, HALF_PI, 0.0)
# After the base, in chain order: (slot of the joint within the finger's 4, its origin).
FINGER_CHAIN: tuple[tuple[int, Origin], ...] = (
    (0, ((-0.0122, 0.0381, 0.0145), (-HALF_PI, 0.0, HALF_PI))),  # mcp_joint -> pip
    (2, ((0.015, 0.0143, -0.013), (HALF_PI, -HALF_PI, 0.0))),  # pip -> dip
    (3, ((0.0, -0.0361, 0.0002), (0.0, 0.0, 0.0))),  # dip -> fingertip
)
THUMB_CHAIN: tuple[tuple[int, Origin], ...] = (  # from palm_lower
    (0, ((-0.069395, -0.001242, -0.021622), (0.0, HALF_PI, 0.0))),  # palm_lower -> pip_4
    (1, ((0.0, 0.0143, -0.013), (HALF_PI, -HALF_PI, 0.0))),  # pip_4 -> thumb_pip
    (2, ((0.0, 0.0145, -0.017), (-HALF_PI, 0.0, 0.0))),  # thumb_pip -> thumb_dip
    (3, ((0.0, 0.0466, 0.0002), (0.0, 0.0, np.pi))),  # thumb_dip -> thumb_fingertip
)
FINGER_LIMITS = ((-1.047, 1.047), (-0.314, 2.23), (-0.506, 1.885), (-0.366, 2.042))
THUMB_LIMITS = ((-0.349, 2.094), (-0.47, 2.443), (-1.20, 1.90), (-1.34, 1.88))
FINGER_JOINTS = ("mcp_side", "mcp_forward", "pip", "dip")
THUMB_JOINTS = ("cmc", "axial", "mcp", "ip")

# The project's palm frame in the URDF's palm_lower frame (see the module docstring).
PALM_ORIGIN_URDF = (-0.007095, -0.037292, -0.018722)  # joint 5 origin moved to the mid-plane
PALM_R_URDF = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # rows: palm axes

# DIGIT mount on the distal link (an assumption: measure your mount and change these).
# Distal link frame (at the DIP/IP axis): the finger continues along -y, the pad faces -x,
# the link's mid-plane is z = +14.5 mm (fingers) / -14.5 mm (thumb) (mesh and collision
# geometry of the URDF / Menagerie model).
DIGIT_ALONG_M = 0.030  # gel centre beyond the DIP/IP axis, along the finger
DIGIT_PAD_M = 0.013  # gel surface from the joint axis toward the pad
MID_PLANE_Z_M = {"finger": 0.0145, "thumb": -0.0145}
# Sensor axes (OpenCV camera: +z out of the pad, +y toward the finger base) in the link frame.
LINK_R_SENSOR = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


def origin_transform(
    xyz: tuple[float, float, float], rpy: tuple[float, float, float]
) -> np.ndarray:
    """URDF <origin>: translation, then R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = np.cos(rpy[0]), np.sin(rpy[0])
    cp, sp = np.cos(rpy[1]), np.sin(rpy[1])
    cy, sy = np.cos(rpy[2]), np.sin(rpy[2])
    pose = np.eye(4)
    pose[:3, :3] = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    pose[:3, 3] = xyz
    return pose


def joint_rotation(angle: float) -> np.ndarray:
    """Rotation by `angle` about -z (every LEAP joint's axis)."""
    c, s = np.cos(angle), np.sin(angle)
    pose = np.eye(4)
    pose[:2, :2] = [[c, s], [-s, c]]
    return pose


def tip_T_sensor(finger: str) -> np.ndarray:
    """DIGIT camera frame in the finger's distal link frame (gel at +z GEL_DISTANCE_M)."""
    gel = np.array(
        [-DIGIT_PAD_M, -DIGIT_ALONG_M, MID_PLANE_Z_M["thumb" if finger == "thumb" else "finger"]]
    )
    pose = np.eye(4)
    pose[:3, :3] = LINK_R_SENSOR
    pose[:3, 3] = gel - GEL_DISTANCE_M * LINK_R_SENSOR[:, 2]
    return pose


class LeapKinematics:
    """16-joint LEAP Hand; same interface as sim.kinematics.HandKinematics (sensor_poses(q), joint_limits)."""

    def __init__(self, world_T_palm: np.ndarray | None = None) -> None:
        self.world_T_palm = (
            default_world_T_palm() if world_T_palm is None else np.asarray(world_T_palm, float)
        )
        check_pose(self.world_T_palm, "world_T_palm")
        palm_T_urdf = np.eye(4)
        palm_T_urdf[:3, :3] = PALM_R_URDF
        palm_T_urdf[:3, 3] = -PALM_R_URDF @ np.asarray(PALM_ORIGIN_URDF)
        self.world_T_urdf = self.world_T_palm @ palm_T_urdf
        self._tip_T_sensor = {f: tip_T_sensor(f) for f in FINGERS}

    @property
    def joint_names(self) -> list[str]:
        return [
            f"{finger}_{joint}"
            for finger in FINGERS
            for joint in (THUMB_JOINTS if finger == "thumb" else FINGER_JOINTS)
        ]

    @property
    def joint_limits(self) -> np.ndarray:
        """(16, 2) lower and upper limit of each joint, radians (the URDF's)."""
        return np.array([THUMB_LIMITS if f == "thumb" else FINGER_LIMITS for f in FINGERS]).reshape(
            16, 2
        )

    def clip(self, q: np.ndarray) -> np.ndarray:
        limits = self.joint_limits
        return np.clip(q, limits[:, 0], limits[:, 1])

    @staticmethod
    def _chain(finger: str) -> tuple[tuple[int, Origin], ...]:
        if finger == "thumb":
            return THUMB_CHAIN
        return ((1, (FINGER_BASE_XYZ[finger], FINGER_BASE_RPY)), *FINGER_CHAIN)

    def fingertip_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """finger -> world_T_distal-link (the URDF's fingertip / thumb_fingertip frame)."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (16,):
            raise ValueError(f"joint positions must have shape (16,), got {q.shape}")
        poses = {}
        for k, finger in enumerate(FINGERS):
            pose = self.world_T_urdf.copy()
            for slot, (xyz, rpy) in self._chain(finger):
                pose = pose @ origin_transform(xyz, rpy) @ joint_rotation(q[4 * k + slot])
            poses[finger] = pose
        return poses

    def sensor_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """finger -> world_T_sensor (4x4) of its DIGIT for joint positions q (16,)."""
        return {f: pose @ self._tip_T_sensor[f] for f, pose in self.fingertip_poses(q).items()}

    def gel_centres(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """finger -> world position (3,) of the centre of its gel's outer surface."""
        return {
            f: (pose @ np.array([0.0, 0.0, GEL_DISTANCE_M, 1.0]))[:3]
            for f, pose in self.sensor_poses(q).items()
        }
