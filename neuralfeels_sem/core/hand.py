"""The hand conventions every hand model (simulated Allegro-like, LEAP, Allegro) shares.

Fingers are named and ordered FINGERS everywhere (joint blocks, sensor seeds, configs).
Palm frame: fingers extend along +z, the palm face looks along +x, the index finger sits
at +y; `default_world_T_palm` places it in the world, so a config carries over between
the simulator and a real hand.
"""

from __future__ import annotations

import numpy as np

FINGERS = ("index", "middle", "ring", "thumb")


def default_world_T_palm() -> np.ndarray:
    """Palm up (palm +x = world +z), fingers along world +x, 15 cm above the table."""
    pose = np.eye(4)
    pose[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
    pose[:3, 3] = (-0.05, 0.0, 0.15)
    return pose
