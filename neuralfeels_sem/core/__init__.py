"""The bottom layer: what every other package may import, and which imports none of them.

frame (the Frame every sensor backend yields), hand (finger names, palm convention), digit
(DIGIT image size and gel geometry), geometry (the OpenCV camera convention, poses,
intrinsics), materials (the default classes and label values), palette (material colours)
and errors (the UserError family). Layer order: docs/design.md, "Package layout".
"""
