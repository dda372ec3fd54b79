"""Depth of the hand's own model as the camera sees it (pyrender, depth only).

Camera segmentation renders the hand's link meshes at the frame's measured joint angles
from the camera's viewpoint; where the measured depth lies on (or behind) that rendered
surface, the pixel is the hand. Meshes are added to the scene once (cached by identity:
a kinematic model returns the same mesh objects every call) and only moved afterwards.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyrender
import trimesh

from neuralfeels_sem.core.geometry import Intrinsics, check_pose
from neuralfeels_sem.utils.offscreen import LazyOffscreen, intrinsics_camera, opengl_camera_pose

_MAX_CACHED_MESHES = 256


class HandDepthRenderer:
    """Renders (mesh, world_T_mesh) lists to an OpenCV depth image (metres, 0 = no hand)."""

    def __init__(self, intrinsics: Intrinsics) -> None:
        self.intrinsics = intrinsics
        self._scene = pyrender.Scene()
        self._camera_node = self._scene.add(intrinsics_camera(intrinsics, znear=0.02, zfar=5.0))
        self._nodes: dict[int, tuple[trimesh.Trimesh, pyrender.Node]] = {}
        self._gl = LazyOffscreen(intrinsics.width, intrinsics.height)

    def close(self) -> None:
        self._gl.close()

    def render(
        self, world_T_camera: np.ndarray, meshes: Sequence[tuple[trimesh.Trimesh, np.ndarray]]
    ) -> np.ndarray:
        """(H, W) float32 depth of `meshes` seen from the OpenCV camera pose `world_T_camera`."""
        check_pose(world_T_camera, "world_T_camera")
        self._scene.set_pose(self._camera_node, opengl_camera_pose(world_T_camera))
        used = set()
        for mesh, world_T_mesh in meshes:
            key = id(mesh)
            if key not in self._nodes:
                if len(self._nodes) >= _MAX_CACHED_MESHES:
                    raise ValueError(
                        "the hand model returned new meshes every call; return the same "
                        "mesh objects from link_meshes(q) and move them with their poses"
                    )
                node = self._scene.add(pyrender.Mesh.from_trimesh(mesh))
                self._nodes[key] = (mesh, node)  # holding the mesh keeps its id unique
            self._scene.set_pose(self._nodes[key][1], np.asarray(world_T_mesh, np.float64))
            used.add(key)
        for key, (_, node) in self._nodes.items():
            node.mesh.is_visible = key in used
        depth = self._gl.get().render(self._scene, flags=pyrender.RenderFlags.DEPTH_ONLY)
        return np.asarray(depth, np.float32)
