"""pyrender offscreen rendering shared by every layer that renders (sim, perception, eval).

All poses passed in are OpenCV-convention (`core/geometry.py`); the only conversion to
OpenGL happens in `opengl_camera_pose`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pyrender
import pyrender.renderer as _pyrender_renderer

from neuralfeels_sem.core.geometry import OPENGL_T_OPENCV, Intrinsics, check_pose


def opengl_camera_pose(world_T_camera_cv: np.ndarray) -> np.ndarray:
    """Pose of pyrender's OpenGL camera (looks along -z, +y up) for an OpenCV camera pose."""
    check_pose(world_T_camera_cv, "world_T_camera")
    # OPENGL_T_OPENCV is its own inverse: it maps GL-frame points to CV-frame points too.
    return world_T_camera_cv @ OPENGL_T_OPENCV


def intrinsics_camera(
    intrinsics: Intrinsics, znear: float, zfar: float
) -> pyrender.IntrinsicsCamera:
    """pyrender pinhole camera matching OpenCV intrinsics.

    OpenCV puts pixel centres at integer coordinates, pyrender at half-integers (pixel
    corners at integers), so the principal point moves by half a pixel; without this
    every depth is sampled half a pixel off (measured: 0.65 mm median error at 25 cm).
    """
    if not 0 < znear < zfar:
        raise ValueError(f"need 0 < znear < zfar, got znear={znear}, zfar={zfar}")
    return pyrender.IntrinsicsCamera(
        fx=intrinsics.fx,
        fy=intrinsics.fy,
        cx=intrinsics.cx + 0.5,
        cy=intrinsics.cy + 0.5,
        znear=znear,
        zfar=zfar,
    )


class _SingleSampleRenderer(_pyrender_renderer.Renderer):
    """pyrender Renderer with single-sample framebuffers.

    Our renderers only use SEG passes (pyrender turns multisampling off for them), yet
    pyrender allocates 4x multisampled buffers; clearing and resolving those costs 25% of
    a pass on software GL (measured: 11.1 -> 8.6 ms CPU per DIGIT pass), for identical depth.
    """

    def _configure_main_framebuffer(self) -> None:
        allocate = _pyrender_renderer.glRenderbufferStorageMultisample
        _pyrender_renderer.glRenderbufferStorageMultisample = lambda target, _samples, fmt, w, h: (
            allocate(target, 0, fmt, w, h)
        )
        try:
            super()._configure_main_framebuffer()
        finally:
            _pyrender_renderer.glRenderbufferStorageMultisample = allocate

    def _read_main_framebuffer(
        self, scene: pyrender.Scene, flags: int
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """pyrender's read-back without the multisample resolve (the buffer is single-sample).

        Reads straight from the framebuffer we drew into and linearises depth without
        boolean-mask indexing; same outputs as pyrender (depth 0 where nothing was drawn).
        """
        from OpenGL.GL import (
            GL_DEPTH_COMPONENT,
            GL_FLOAT,
            GL_READ_FRAMEBUFFER,
            GL_RGB,
            GL_RGBA,
            GL_UNSIGNED_BYTE,
            glBindFramebuffer,
            glReadPixels,
        )

        width, height = self._main_fb_dims
        glBindFramebuffer(GL_READ_FRAMEBUFFER, self._main_fb_ms)
        raw = np.frombuffer(
            glReadPixels(0, 0, width, height, GL_DEPTH_COMPONENT, GL_FLOAT), np.float32
        )
        raw = raw.reshape(height, width)[::-1]
        znear, zfar = scene.main_camera_node.camera.znear, scene.main_camera_node.camera.zfar
        ndc = 2.0 * raw - 1.0
        if zfar is None:
            depth = (2.0 * znear) / (1.0 - ndc)
        else:
            depth = (2.0 * znear * zfar) / (zfar + znear - ndc * (zfar - znear))
        depth[raw == 1.0] = 0.0
        depth = depth.astype(np.float32, copy=False)
        if flags & pyrender.RenderFlags.DEPTH_ONLY:
            return depth
        channels, fmt = (4, GL_RGBA) if flags & pyrender.RenderFlags.RGBA else (3, GL_RGB)
        colour = np.frombuffer(glReadPixels(0, 0, width, height, fmt, GL_UNSIGNED_BYTE), np.uint8)
        return colour.reshape(height, width, channels)[::-1], depth


def _handle(egl_object) -> int | None:  # noqa: ANN001 - a PyOpenGL EGL handle
    """The address behind an EGL handle (None for a null one), to compare handles."""
    import ctypes

    if egl_object is None:
        return None
    return ctypes.cast(egl_object, ctypes.c_void_p).value


class _EglCurrent(NamedTuple):
    """What is current on this thread: eglMakeCurrent's arguments and the context's address."""

    display: object
    draw: object
    read: object
    context_id: int | None
    context: object


def _current_egl() -> _EglCurrent:
    """The EGL display, surfaces and context current on this thread."""
    from OpenGL.EGL import (
        EGL_DRAW,
        EGL_READ,
        eglGetCurrentContext,
        eglGetCurrentDisplay,
        eglGetCurrentSurface,
    )

    context = eglGetCurrentContext()
    surfaces = (eglGetCurrentSurface(EGL_DRAW), eglGetCurrentSurface(EGL_READ))
    return _EglCurrent(eglGetCurrentDisplay(), *surfaces, _handle(context), context)


class _OffscreenKeepingDisplay(pyrender.OffscreenRenderer):
    """OffscreenRenderer whose delete() frees only its own EGL context.

    pyrender's EGL delete() calls eglTerminate on the display, which every context of
    the process shares (the other fingers' renderers, the camera, MuJoCo's renderer):
    closing or garbage-collecting one renderer would break all the others (EGL_BAD_DISPLAY).
    It also renders with single-sample framebuffers (see _SingleSampleRenderer).
    """

    def _create(self) -> None:
        super()._create()
        # pyrender's Renderer allocates no GL objects before its first render: swap it.
        self._renderer = _SingleSampleRenderer(self.viewport_width, self.viewport_height)

    def delete(self) -> None:
        platform = getattr(self, "_platform", None)
        if platform is None or not hasattr(platform, "_egl_display"):
            if platform is not None:
                super().delete()
            return
        from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglDestroyContext, eglMakeCurrent

        if platform._egl_context is not None:
            # The garbage collector may delete a renderer in the middle of another one's
            # render on this thread: that one gets its context back afterwards.
            previous = _current_egl()
            platform.make_current()
            self._renderer.delete()
            eglMakeCurrent(platform._egl_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
            eglDestroyContext(platform._egl_display, platform._egl_context)
            if previous.context_id not in (None, _handle(platform._egl_context)):
                eglMakeCurrent(previous.display, previous.draw, previous.read, previous.context)
            platform._egl_context = None
        platform._egl_display = None  # the platform's own __del__ would eglTerminate it
        self._renderer = None
        self._platform = None


class LazyOffscreen:
    """An OffscreenRenderer created on first use, so constructors stay cheap and GL-free."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self._renderer: pyrender.OffscreenRenderer | None = None

    def get(self) -> pyrender.OffscreenRenderer:
        if self._renderer is None:
            self._renderer = _OffscreenKeepingDisplay(self.width, self.height)
        return self._renderer

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.delete()
            self._renderer = None
