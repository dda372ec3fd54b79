"""Offscreen depth rendering of a mesh from fixed views (pyrender on EGL).

Poses and intrinsics are OpenCV (core/geometry.py); the conversion to pyrender's OpenGL
camera happens in `DepthRenderer.render` and nowhere else.
"""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.core.geometry import OPENGL_T_OPENCV, Intrinsics, check_pose, look_at


def orbit_views(
    center: np.ndarray,
    radius: float,
    views: int = 4,
    elevation_deg: float = 30.0,
    fov_y_deg: float = 40.0,
    azimuth_offset_deg: float = 0.0,
    margin: float = 1.1,
) -> list[np.ndarray]:
    """`views` OpenCV cameras (object_T_camera) evenly spaced in azimuth around `center`,
    far enough that a sphere of `radius` fills the field of view (times `margin`)."""
    if views < 1 or radius <= 0:
        raise ValueError(f"orbit_views needs views >= 1 and radius > 0, got {views}, {radius}")
    distance = margin * radius / np.sin(np.deg2rad(fov_y_deg) / 2.0)
    elevation = np.deg2rad(elevation_deg)
    poses = []
    for i in range(views):
        azimuth = np.deg2rad(azimuth_offset_deg + 360.0 * i / views)
        direction = np.array(
            [
                np.cos(elevation) * np.cos(azimuth),
                np.cos(elevation) * np.sin(azimuth),
                np.sin(elevation),
            ]
        )
        poses.append(look_at(center + distance * direction, center))
    return poses


class DepthRenderer:
    """Renders metric depth (OpenCV z, 0 = background) of one mesh; the GL context opens on first use."""

    def __init__(self, mesh: trimesh.Trimesh, intrinsics: Intrinsics) -> None:
        self.mesh = mesh
        self.intrinsics = intrinsics
        self._renderer = None
        self._scene = None
        self._camera_node = None

    def _open(self) -> None:
        import pyrender

        # Shared with the sim renderers: its close() keeps the process-wide EGL display alive
        # (pyrender's own delete() would terminate it under every other renderer).
        from neuralfeels_sem.utils.offscreen import LazyOffscreen, intrinsics_camera

        self._center = self.mesh.bounds.mean(axis=0)
        self._radius = float(np.linalg.norm(self.mesh.vertices - self._center, axis=1).max())
        # intrinsics_camera moves the principal point by half a pixel (OpenCV pixel centres).
        camera = intrinsics_camera(self.intrinsics, znear=0.01, zfar=10.0)
        self._scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 0.0], ambient_light=[1.0, 1.0, 1.0])
        self._scene.add(pyrender.Mesh.from_trimesh(self.mesh, smooth=False))
        self._camera_node = self._scene.add(camera, pose=np.eye(4))
        self._renderer = LazyOffscreen(self.intrinsics.width, self.intrinsics.height)

    def render(self, object_T_camera: np.ndarray) -> np.ndarray:
        """(H, W) float32 depth in metres along the camera's +z; 0 where the mesh is not seen."""
        check_pose(object_T_camera, "object_T_camera")
        import pyrender

        if self._renderer is None:
            self._open()
        # Near and far planes hug the object, so the 24-bit depth buffer keeps sub-0.1 mm precision.
        dist = float(np.linalg.norm(object_T_camera[:3, 3] - self._center))
        camera = self._camera_node.camera
        camera.znear, camera.zfar = (
            max(1e-4, dist - 1.05 * self._radius),
            dist + 1.05 * self._radius,
        )
        self._scene.set_pose(self._camera_node, object_T_camera @ OPENGL_T_OPENCV)
        depth = self._renderer.get().render(self._scene, flags=pyrender.RenderFlags.DEPTH_ONLY)
        return np.asarray(depth, dtype=np.float32)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> DepthRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
