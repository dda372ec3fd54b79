"""Hand kinematic models by name (sensor.hand.kinematics): each gives DIGIT poses from joints.

A model class takes `world_T_palm` (4x4) and has `joint_limits` (16, 2) and
`sensor_poses(q) -> {finger: world_T_sensor}`; a dotted class path selects your own.
"""

from __future__ import annotations

KINEMATICS = {
    "allegro": "neuralfeels_sem.sim.kinematics.HandKinematics",  # the sim's Allegro-like hand
    "leap": "neuralfeels_sem.sensors.real.leap_kinematics.LeapKinematics",  # LEAP Hand URDF
}


def kinematics_target(name: str) -> str:
    """Class path of the model `name` (a known name, or already a class path)."""
    if name in KINEMATICS:
        return KINEMATICS[name]
    if "." not in name:
        raise ValueError(
            f"sensor.hand.kinematics={name!r} is unknown: use {', '.join(KINEMATICS)} or a class path with sensor_poses(q)"
        )
    return name
