"""SemanticFeels: online shape and material mapping from vision and touch."""

import os

# Headless rendering defaults; must be set before OpenGL / MuJoCo are imported anywhere.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("MUJOCO_GL", "egl")
# pyrender imports pyglet's window module only for its viewer class. pyglet's default
# backend loads X11 libraries (libX11, libXrender) that a headless GPU server may lack, so
# pyglet runs headless; and without a shadow window, since headless pyglet would otherwise
# create an EGL context of its own on import and make it current under pyrender's.
os.environ.setdefault("PYGLET_HEADLESS", "true")
os.environ.setdefault("PYGLET_SHADOW_WINDOW", "false")

__version__ = "0.1.0"
