"""SemanticFeels: online shape and material mapping from vision and touch."""

import os

# Headless rendering defaults; must be set before OpenGL / MuJoCo are imported anywhere.
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
