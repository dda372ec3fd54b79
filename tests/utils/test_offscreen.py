"""Deleting one offscreen renderer leaves the EGL context current on this thread alone."""

from __future__ import annotations

import numpy as np
import pyrender
import pytest
import trimesh

from neuralfeels_sem.utils.offscreen import LazyOffscreen, _current_egl, _handle


def _scene() -> pyrender.Scene:
    scene = pyrender.Scene()
    scene.add(pyrender.Mesh.from_trimesh(trimesh.creation.box(extents=(0.1, 0.1, 0.1))))
    camera = pyrender.IntrinsicsCamera(fx=100, fy=100, cx=32, cy=32, znear=0.01, zfar=2.0)
    pose = np.eye(4)
    pose[2, 3] = 0.5
    scene.add(camera, pose=pose)
    return scene


def test_deleting_a_renderer_gives_the_current_context_back() -> None:
    # The garbage collector can delete a renderer while another one is between making its
    # context current and drawing (seen: a render failing with "no valid context" after a
    # live-view run's renderers were collected in the same process).
    first, second = LazyOffscreen(64, 64), LazyOffscreen(64, 64)
    try:
        scene = _scene()  # a mesh binds to one context: each renderer draws its own scene
        flags = pyrender.RenderFlags.DEPTH_ONLY
        first.get().render(scene, flags)
        second.get().render(_scene(), flags)
        first.get()._platform.make_current()
        mine = _handle(first.get()._platform._egl_context)
        assert _current_egl()[3] == mine
        second.close()  # as the garbage collector would, mid-render of `first`
        assert _current_egl()[3] == mine
        depth = first.get().render(scene, flags)
        assert np.isfinite(depth).all() and depth.max() > 0
    finally:
        first.close()
        second.close()


def test_deleting_the_current_renderer_leaves_no_context_current() -> None:
    only = LazyOffscreen(32, 32)
    only.get().render(_scene(), pyrender.RenderFlags.DEPTH_ONLY)
    only.close()
    if _current_egl()[3] is not None:
        pytest.fail("the deleted renderer's context is still current")
