"""Geometry of a DIGIT, shared by the hand models, the renderers, perception and the real rig.

Sensor frame = the DIGIT's internal camera, OpenCV convention: +z looks out through
the gel toward the object, +x along the image columns (240 px), +y along the rows
(320 px). The gel's outer surface is the plane z = GEL_DISTANCE_M; an object point
touches the gel when its depth along +z is below that plane, and the gel can be
pressed in by at most MAX_PENETRATION_M.
"""

from neuralfeels_sem.core.geometry import Intrinsics

DIGIT_HEIGHT, DIGIT_WIDTH = 320, 240  # image rows x columns (QVGA portrait)

GEL_WIDTH_M = 0.018  # along +x (image columns)
GEL_HEIGHT_M = 0.024  # along +y (image rows)
GEL_DISTANCE_M = 0.020  # camera centre to the gel's outer surface along +z
MAX_PENETRATION_M = 0.0025  # deepest press the gel can take

# Pinhole model whose view exactly spans the gel at the gel plane (square pixels).
_FOCAL = (DIGIT_WIDTH / 2.0) * GEL_DISTANCE_M / (GEL_WIDTH_M / 2.0)
DIGIT_INTRINSICS = Intrinsics(
    fx=_FOCAL,
    fy=(DIGIT_HEIGHT / 2.0) * GEL_DISTANCE_M / (GEL_HEIGHT_M / 2.0),
    cx=(DIGIT_WIDTH - 1) / 2.0,
    cy=(DIGIT_HEIGHT - 1) / 2.0,
    width=DIGIT_WIDTH,
    height=DIGIT_HEIGHT,
)
