"""SemanticFeels: online shape and material mapping from vision and touch."""

import os

# Headless rendering defaults; must be set before OpenGL / MuJoCo are imported anywhere.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("MUJOCO_GL", "egl")
# pyrender imports pyglet's window module, whose default backend loads X11 libraries
# (libX11, libXrender) that a headless GPU server may not have; headless pyglet uses EGL.
os.environ.setdefault("PYGLET_HEADLESS", "true")

__version__ = "0.1.0"
