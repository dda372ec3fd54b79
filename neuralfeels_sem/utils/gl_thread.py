"""Let go of the OpenGL context a finishing thread holds current.

An EGL context stays current to the thread that last rendered with it, even after that
thread has ended; closing its renderer from another thread then fails (EGL_BAD_ACCESS).
A thread that rendered (the mapping run's frame producer) calls this before it ends.
"""

from __future__ import annotations

import os


def release_thread_gl() -> None:
    """Release this thread's current EGL context, if EGL is the platform and was loaded."""
    if os.environ.get("PYOPENGL_PLATFORM") != "egl":
        return
    try:
        from OpenGL.EGL import eglReleaseThread
    except ImportError:  # a rig without PyOpenGL renders nothing
        return
    eglReleaseThread()
