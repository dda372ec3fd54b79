"""Tuning of the simulated rig: postures, contact sampling, press control, clearances."""

from __future__ import annotations

import numpy as np

DEFAULT_PRESS_M = {"index": 0.0015, "middle": 0.0015, "ring": 0.0015, "thumb": 0.0007}
# Posture of fingers that take no part (bent back, away from the object) and the IK start.
REST_Q = np.array([0.0, -0.19, 0.0, 0.0] * 3 + [0.263, 0.0, 0.0, 0.0])
# Natural grasp posture: pads of fingers and thumb face each other; index and ring turned
# in toward the middle finger as far as their DIGITs stay clear of its DIGIT (5 mm).
NOMINAL_Q = np.array(
    [0.25, 0.6, 0.6, 0.5, 0.0, 0.6, 0.6, 0.5, -0.25, 0.6, 0.6, 0.5, 1.25, 0.1, 0.3, 0.3]
)
# Joint boxes (rad, within the limits) contact postures are drawn from. Index and ring may
# converge on the middle finger with their MCP abduction (j0) up to the joint limit: their
# pads then reach objects narrower than the 43.5 mm finger spacing (with the gel's inner
# edge where the surface turns away). The middle finger stays central; the thumb near its
# natural posture (it opposes the middle finger).
SAMPLE_BOX = {
    "index": np.array([[0.0, 0.47], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "middle": np.array([[-0.3, 0.3], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "ring": np.array([[-0.47, 0.0], [-0.1, 1.4], [0.0, 1.6], [0.0, 1.6]]),
    "thumb": np.array([[0.8, 1.396], [-0.105, 0.9], [-0.189, 1.2], [-0.162, 1.2]]),
}
SAMPLE_TRIES = 96  # postures drawn per new contact
ENOUGH_TOUCHES = 24  # stop drawing once this many qualify
FIRST_TRIES = 288  # while the finger has not touched yet
LIBRARY_TRIES = 2000  # box postures screened once per finger for ones near the object
# A touching gel centre lies at most the press inside the surface, and outside by up to
# MAX_SHIFT_M plus, for a tilted pad touching with its edge, most of the gel's half width.
LIBRARY_INSIDE_M, LIBRARY_OUTSIDE_M = 0.003, 0.025
MIN_LIBRARY = 32  # fewer screened postures than this: draw from the whole box
PROFILE_BIN_M = 0.004  # height bins of the object's swept profile
LOCAL_SHARE = 0.5  # share drawn around postures that touched before (narrow objects: few do)
LOCAL_JITTER_RAD = 0.12
MEMORY = 12  # touching postures remembered per finger
COMPAT_CANDIDATES = 5  # best sampled touches ranked by the room they leave the others
RECENT = 2  # latest touches per other finger that count as its room
VERIFY_CANDIDATES = 10  # best sampled touches checked by IK and for clearance
PRESS_CONTROL_ROUNDS = 3  # per time step
PRESS_ROUNDS = 4  # IK rounds that bring a sampled touch to its press depth
PRESS_TOLERANCE_M = 3e-4
PRESS_SHORTFALL_M = 1e-3  # a finger at the edge of its reach may press this much less
MIN_PRESS_M = 3e-4
MAX_SHIFT_M = 0.015  # a sampled gel may be at most this far from its touch along its pad
MIN_CONTACT_RAYS = 3  # of the 25 gel rays, in contact at the press depth (a tilted touch
GOOD_CONTACT_RAYS = 10  # meets the object with its edge); more than GOOD counts the same
MIN_PRESSED_RAYS = 2  # once pressed to its firmness (the IK turns a tilted pad a little)
BOTTOM_COS = 0.7  # no touches where the surface faces the palm this squarely (the resting
# bottom of an object is unlabelled, and there is no room there for a finger), nor, on an
# object with a flat base, where it faces the object's own -z this squarely: the base it
# stands on, which a second rotation axis brings round to the fingers. A flat base fills
# the whole gel, unlike any press the classifier was trained on.
FLAT_BASE_SHARE = 0.02  # of the surface area facing -z within 8 degrees: a flat base
FINGER_CLEARANCE_M = 0.001  # gap kept between a new contact's finger and the busy fingers
OVERLAP_TOLERANCE_M = 0.001  # fingers closer than -this are pulled apart at run time
# Order in which fingers plan (and so claim room for) new contacts when several do at once:
# the middle finger first, it sits between the others and the thumb opposes it.
PLAN_ORDER = ("middle", "thumb", "index", "ring")
HOVER_BACK_M = 0.015  # a finger with nothing to touch waits this far behind its natural place
PALM_CLEARANCE_M = 0.008
# The object sits this much further out along the fingers than midway between the middle
# finger's and the thumb's natural pads: index and ring, which reach the object only
# where their lines converge on it, gain much more room than the thumb loses.
GRASP_REACH_M = 0.015
RETRY_IK_M = 0.001  # IK error above which a finger retries from its contact's posture
LOST_CONTACT_M = 0.003  # a touching finger further than this from its target gives up the contact


def flat_base_share(mesh) -> float:
    """Share of a mesh's surface area facing its -z within 8 degrees (a flat base)."""
    area = np.asarray(mesh.area_faces)
    down = np.asarray(mesh.face_normals)[:, 2] < -0.99
    return float(area[down].sum() / max(area.sum(), 1e-12))
