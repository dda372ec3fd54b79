"""MJCF of a four-finger, 16-joint hand with Allegro-like kinematics and a DIGIT per fingertip.

Palm frame: fingers extend along +z, the palm face (and every fingertip pad when the
fingers are straight) looks along +x, the index finger sits at +y. Link lengths and
joint limits follow the Allegro hand (right); the thumb is our own 4-joint chain with
Allegro lengths and limits: opposition (swings the thumb from the side of the palm to
in front of it), twist about its proximal link, then two flexion joints.

Each fingertip carries a DIGIT: site `<finger>_digit` is the sensor frame (the internal
camera, OpenCV: +z out of the pad toward the object, +y along the finger toward its
base = image rows); site `<finger>_gel` is the centre of the gel's outer surface,
GEL_DISTANCE_M along +z. Joint order is the Allegro one: index 0-3, middle 4-7,
ring 8-11, thumb 12-15.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.hand import FINGERS

LINK_RADIUS = 0.0098  # Allegro links are 19.6 mm wide
PALM_CENTRE = (-0.0093, 0.0, -0.0475)
PALM_HALF = (0.0204, 0.0565, 0.0475)
PALM_FACE_X = PALM_CENTRE[0] + PALM_HALF[0]  # the palm's front face in the palm frame

FINGER_LIMITS = ((-0.47, 0.47), (-0.196, 1.61), (-0.174, 1.709), (-0.227, 1.618))
THUMB_LIMITS = ((0.263, 1.396), (-0.105, 1.163), (-0.189, 1.644), (-0.162, 1.719))
FINGER_LENGTHS = (0.0164, 0.054, 0.0384)  # joint 0 -> 1 -> 2 -> 3
THUMB_LENGTHS = (0.045, 0.0177, 0.0514)  # joint 12 -> 13 -> 14 -> 15
FINGER_BASES = {
    "index": (0.0, 0.0435, -0.001542),
    "middle": (0.0, 0.0, 0.0007),
    "ring": (0.0, -0.0435, -0.001542),
}
FINGER_SPLAY_RAD = {
    "index": -0.0873,
    "middle": 0.0,
    "ring": 0.0873,
}  # Allegro's 5 degree splay about x
THUMB_BASE = (
    -0.0182,
    0.0,
    -0.045987,
)  # Allegro: y = 0.019; centred here to oppose the middle finger

# DIGIT on the distal link (frame at the last joint, link along +z, pad toward +x).
DIGIT_ALONG = 0.025  # gel centre distance from the last joint along the finger
DIGIT_PAD_X = LINK_RADIUS + 0.0032  # gel surface offset from the link axis
# (along pad normal, across, along finger); across: a DIGIT is about 20 mm wide (the gel
# 18 mm), so neighbouring fingertips can touch a narrow object side by side
DIGIT_BOX_HALF = (0.0115, 0.0103, 0.016)
# Rotation distal-link <- sensor: x_s = -y, y_s = -z (toward the finger base), z_s = +x.
LINK_R_SENSOR = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class JointSpec:
    name: str
    lower: float
    upper: float


def joint_specs() -> list[JointSpec]:
    """The 16 joints in Allegro order with their limits (radians)."""
    specs = []
    for finger in FINGERS:
        limits = THUMB_LIMITS if finger == "thumb" else FINGER_LIMITS
        specs += [JointSpec(f"{finger}_j{i}", lo, hi) for i, (lo, hi) in enumerate(limits)]
    return specs


def _fmt(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.ravel(values))


def _mat_to_quat(rot: np.ndarray) -> np.ndarray:
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot, dtype=np.float64).ravel())
    return quat


def _joint(name: str, axis: str, lo: float, hi: float) -> str:
    return f'<joint name="{name}" axis="{axis}" range="{lo:.6g} {hi:.6g}"/>'


def _capsule(name: str, length: float) -> str:
    return (
        f'<geom name="{name}" type="capsule" fromto="0 0 0 0 0 {length:.6g}" size="{LINK_RADIUS}" '
        f'class="hand_link"/>'
    )


def _digit(finger: str) -> str:
    """DIGIT body geometry and its two sites, in the distal link frame."""
    box_centre = (DIGIT_PAD_X - DIGIT_BOX_HALF[0], 0.0, DIGIT_ALONG)
    sensor_pos = (DIGIT_PAD_X - GEL_DISTANCE_M, 0.0, DIGIT_ALONG)
    gel_pos = (DIGIT_PAD_X, 0.0, DIGIT_ALONG)
    quat = _fmt(_mat_to_quat(LINK_R_SENSOR))
    return (
        f'<geom name="{finger}_digit_body" type="box" pos="{_fmt(box_centre)}" size="{_fmt(DIGIT_BOX_HALF)}" '
        f'class="hand_digit"/>'
        f'<site name="{finger}_digit" pos="{_fmt(sensor_pos)}" quat="{quat}" size="0.002"/>'
        f'<site name="{finger}_gel" pos="{_fmt(gel_pos)}" quat="{quat}" size="0.002"/>'
    )


def _finger(finger: str) -> str:
    (l0, l1, l2), lims = FINGER_LENGTHS, FINGER_LIMITS
    splay = FINGER_SPLAY_RAD[finger]
    quat = _fmt([np.cos(splay / 2), np.sin(splay / 2), 0.0, 0.0])
    return (
        f'<body name="{finger}_base" pos="{_fmt(FINGER_BASES[finger])}" quat="{quat}">'
        f"{_joint(f'{finger}_j0', '1 0 0', *lims[0])}{_capsule(f'{finger}_link0', l0)}"
        f'<body name="{finger}_proximal" pos="0 0 {l0}">'
        f"{_joint(f'{finger}_j1', '0 1 0', *lims[1])}{_capsule(f'{finger}_link1', l1)}"
        f'<body name="{finger}_middle" pos="0 0 {l1}">'
        f"{_joint(f'{finger}_j2', '0 1 0', *lims[2])}{_capsule(f'{finger}_link2', l2)}"
        f'<body name="{finger}_distal" pos="0 0 {l2}">'
        f"{_joint(f'{finger}_j3', '0 1 0', *lims[3])}{_digit(finger)}"
        "</body></body></body></body>"
    )


def _thumb() -> str:
    (l0, l1, l2), lims = THUMB_LENGTHS, THUMB_LIMITS
    # Base frame: z along palm +y (thumb sticks out sideways at joint 12 = 0), x along palm +z
    # (the pad faces the fingertips), y = z x x = palm +x. Opposition about -x swings it to the front.
    base_rot = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    quat = _fmt(_mat_to_quat(base_rot))
    return (
        f'<body name="thumb_base" pos="{_fmt(THUMB_BASE)}" quat="{quat}">'
        f"{_joint('thumb_j0', '-1 0 0', *lims[0])}{_capsule('thumb_link0', l0)}"
        f'<body name="thumb_proximal" pos="0 0 {l0}">'
        f"{_joint('thumb_j1', '0 0 1', *lims[1])}{_capsule('thumb_link1', l1)}"
        f'<body name="thumb_middle" pos="0 0 {l1}">'
        f"{_joint('thumb_j2', '0 1 0', *lims[2])}{_capsule('thumb_link2', l2)}"
        f'<body name="thumb_distal" pos="0 0 {l2}">'
        f"{_joint('thumb_j3', '0 1 0', *lims[3])}{_digit('thumb')}"
        "</body></body></body></body>"
    )


def hand_defaults_xml() -> str:
    """Default classes the hand bodies use (goes inside <default>)."""
    # Hand-object collision is off: the object is driven kinematically and contact is
    # rendered from geometry, so the solver never fights a mocap body.
    return (
        '<default class="hand_link"><geom contype="0" conaffinity="0" group="1" rgba="0.15 0.15 0.15 1"/></default>'
        '<default class="hand_digit"><geom contype="0" conaffinity="0" group="1" rgba="0.8 0.8 0.82 1"/></default>'
        '<default class="hand_joint"><joint damping="0.1" armature="0.001"/></default>'
    )


def hand_body_xml(world_T_palm: np.ndarray) -> str:
    """The hand as one <body> tree (goes inside <worldbody>); gravity-compensated."""
    pos, quat = _fmt(world_T_palm[:3, 3]), _fmt(_mat_to_quat(world_T_palm[:3, :3]))
    palm = f'<geom name="palm" type="box" pos="{_fmt(PALM_CENTRE)}" size="{_fmt(PALM_HALF)}" class="hand_link"/>'
    fingers = "".join(_finger(f) for f in FINGERS if f != "thumb") + _thumb()
    fingers = fingers.replace("<body ", '<body gravcomp="1" ')
    return (
        f'<body name="palm" pos="{pos}" quat="{quat}" gravcomp="1" childclass="hand_joint">'
        f'<inertial pos="{_fmt(PALM_CENTRE)}" mass="0.4" diaginertia="1e-3 1e-3 1e-3"/>'
        f"{palm}{fingers}</body>"
    )


def hand_actuators_xml(kp: float = 20.0) -> str:
    """Position servos on all 16 joints (hold the commanded posture when physics steps)."""
    return "".join(
        f'<position name="{s.name}_servo" joint="{s.name}" kp="{kp}" kv="0.5" ctrlrange="{s.lower:.6g} {s.upper:.6g}"/>'
        for s in joint_specs()
    )


def hand_only_xml(world_T_palm: np.ndarray) -> str:
    """A model with just the hand (for kinematics without a scene)."""
    return (
        '<mujoco model="hand"><compiler angle="radian" autolimits="true"/>'
        '<option gravity="0 0 -9.81"/>'
        f"<default>{hand_defaults_xml()}</default>"
        f"<worldbody>{hand_body_xml(world_T_palm)}</worldbody>"
        f"<actuator>{hand_actuators_xml()}</actuator></mujoco>"
    )
