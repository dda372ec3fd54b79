"""The external RGB-D camera (the paper's front-left view) rendered with pyrender.

One pyrender segmentation pass gives, per pixel, depth and what is seen (object
material, table, occluder or nothing); colour is then shaded in numpy from the
palette below and normals of the depth map (a key light from above, a headlight and
ambient). On a software-GL CPU this is about 2.5x cheaper than pyrender's PBR colour
pass, and the segmentation pass has no multisampling, so depth is exact at pixel
centres (the multisampled colour pass's depth is off by a sub-pixel sample offset).

Depth: metres along the OpenCV +z axis, 0 where nothing was rendered; optional
RealSense-like depth noise (sim/depth_noise.py). Mask: pixels where the object is the
visible surface (occluders such as finger links, and the lab scenery: table, backdrop,
the hand's mount, hide it and are never in it).
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence

import numpy as np
import pyrender
import trimesh

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.core.geometry import Intrinsics, check_pose, look_at
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.sim.depth_noise import (
    DEPTH_NOISE_MODELS,
    RealSenseDepthNoise,
    RealSenseNoiseConfig,
)
from neuralfeels_sem.sim.pyrender_utils import split_by_material
from neuralfeels_sem.utils.offscreen import LazyOffscreen, intrinsics_camera, opengl_camera_pose

# RGB 0..1 per material name; unknown names get a stable colour from their name.
MATERIAL_PALETTE: dict[str, tuple[float, float, float]] = {
    "plastic": (0.20, 0.45, 0.85),
    "metal": (0.72, 0.74, 0.78),
    "fabric": (0.85, 0.30, 0.35),
    "wood": (0.62, 0.42, 0.22),
}
IGNORE_COLOUR = (0.45, 0.45, 0.45)
TABLE_COLOUR = (0.55, 0.52, 0.48)
OCCLUDER_COLOUR = (0.15, 0.15, 0.15)


def material_colour(name: str) -> tuple[float, float, float]:
    """Palette colour of a material name (RGB 0..1), stable for names outside the palette."""
    if name.lower() in MATERIAL_PALETTE:
        return MATERIAL_PALETTE[name.lower()]
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    return tuple(float(c) for c in rng.uniform(0.2, 0.9, 3))


def front_left_camera_pose(
    target: np.ndarray,
    distance: float = 0.35,
    azimuth_deg: float = 45.0,
    elevation_deg: float = 35.0,
) -> np.ndarray:
    """world_T_camera (OpenCV) looking at `target` from the front-left, from above.

    World frame: z up. The camera sits `distance` from the target at `azimuth_deg` from
    world +x toward +y (the default hand points its fingers along +x, so 45 degrees is
    in front of the fingertips and to the hand's left) and `elevation_deg` above the
    horizontal.
    """
    if distance <= 0:
        raise ValueError(f"camera distance must be > 0, got {distance}")
    az, el = np.deg2rad(azimuth_deg), np.deg2rad(elevation_deg)
    offset = distance * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    target = np.asarray(target, np.float64)
    return look_at(target + offset, target)


_NOTHING, _TABLE, _OCCLUDER, _FIRST_OBJECT = 0, 1, 2, 3  # segmentation codes (one uint8 channel)
_MAX_CACHED_OCCLUDERS = 256
_AMBIENT, _KEY, _HEAD = 0.3, 0.5, 0.35  # light mix of the numpy shading
_KEY_DIR_WORLD = np.array([0.3, -0.2, 1.0]) / np.linalg.norm(
    [0.3, -0.2, 1.0]
)  # toward the key light


class CameraRenderer:
    """Renders one RGB-D camera watching one MaterialObject (plus optional occluders).

    Args:
        obj: the object.
        width, height: image size in pixels.
        fov_y_deg: vertical field of view.
        world_T_camera: OpenCV camera pose; default: `front_left_camera_pose` of the origin.
        depth_noise: "none" (exact depth) or "realsense" (sim/depth_noise.py).
        realsense: RealSenseNoiseConfig keyword arguments (with depth_noise="realsense").
        seed: depth-noise seed.
        table_height: world z of a table top to render under the object; None = no table.
        scenery: static (mesh, world_T_mesh) seen behind the object (backdrop, mount);
            coloured and coded like the table, never part of the mask.
        name: camera name stored in each CameraReading.
    """

    def __init__(
        self,
        obj: MaterialObject,
        width: int = 320,
        height: int = 240,
        fov_y_deg: float = 50.0,
        world_T_camera: np.ndarray | None = None,
        depth_noise: str = "none",
        realsense: dict | None = None,
        seed: int = 0,
        table_height: float | None = None,
        scenery: Sequence[tuple[trimesh.Trimesh, np.ndarray]] = (),
        name: str = "front_left",
    ) -> None:
        if width < 1 or height < 1 or not 0 < fov_y_deg < 180:
            raise ValueError(
                f"need width, height >= 1, 0 < fov_y_deg < 180; got {width}, {height}, {fov_y_deg}"
            )
        if depth_noise not in DEPTH_NOISE_MODELS:
            raise ValueError(f"depth_noise={depth_noise!r}: use one of {DEPTH_NOISE_MODELS}")
        self.obj = obj
        self.name = name
        self.intrinsics = Intrinsics.from_fov(width, height, fov_y_deg)
        self.depth_noise = (
            RealSenseDepthNoise(RealSenseNoiseConfig(**(realsense or {})), self.intrinsics, seed)
            if depth_noise == "realsense"
            else None
        )
        self._scene = pyrender.Scene()
        self._seg_map: dict[pyrender.Node, int] = {}
        self._add_object(obj)
        self._add_scenery(table_height, scenery)
        self._occluder_nodes: dict[int, tuple[trimesh.Trimesh, pyrender.Node]] = {}

        self._camera_node = self._scene.add(
            intrinsics_camera(self.intrinsics, znear=0.02, zfar=5.0)
        )
        self.set_camera_pose(
            front_left_camera_pose(np.zeros(3)) if world_T_camera is None else world_T_camera
        )
        self._gl = LazyOffscreen(width, height)
        # Unit rays through each pixel (z = 1), for normals from depth.
        v, u = np.mgrid[0:height, 0:width].astype(np.float32)
        self._ray_x = (u - self.intrinsics.cx) / self.intrinsics.fx
        self._ray_y = (v - self.intrinsics.cy) / self.intrinsics.fy

    def _add_object(self, obj: MaterialObject) -> None:
        """One node per material, each with its segmentation code and colour."""
        # Colour per segmentation code: nothing, table, occluder, then one per object label.
        palette = [(0.0, 0.0, 0.0), TABLE_COLOUR, OCCLUDER_COLOUR]
        if len(obj.class_names) + _FIRST_OBJECT + 1 > 256:
            raise ValueError(
                f"the camera renderer handles at most 252 materials, got {len(obj.class_names)}"
            )
        self._object_nodes: list[pyrender.Node] = []
        for label, sub in split_by_material(obj):
            node = self._scene.add(pyrender.Mesh.from_trimesh(sub, smooth=True))
            self._object_nodes.append(node)
            self._seg_map[node] = _FIRST_OBJECT + len(palette) - 3
            palette.append(
                IGNORE_COLOUR if label == IGNORE else material_colour(obj.class_names[label])
            )
        self._palette = np.asarray(palette, np.float32)

    def _add_scenery(
        self,
        table_height: float | None,
        scenery: Sequence[tuple[trimesh.Trimesh, np.ndarray]],
    ) -> None:
        """The table (if any) and the lab's other surfaces, all segmented as scenery."""
        self._table_node: pyrender.Node | None = None
        if table_height is not None:
            table = trimesh.creation.box(extents=(1.5, 1.5, 0.02))
            pose = np.eye(4)
            pose[2, 3] = table_height - 0.01
            self._table_node = self._scene.add(pyrender.Mesh.from_trimesh(table), pose=pose)
            self._seg_map[self._table_node] = _TABLE
        for mesh, world_T_mesh in scenery:
            check_pose(world_T_mesh, "scenery pose")
            node = self._scene.add(pyrender.Mesh.from_trimesh(mesh), pose=world_T_mesh)
            self._seg_map[node] = _TABLE

    @property
    def world_T_camera(self) -> np.ndarray:
        return self._world_T_camera.copy()

    def set_camera_pose(self, world_T_camera: np.ndarray) -> None:
        """Move the camera (OpenCV pose)."""
        check_pose(world_T_camera, "world_T_camera")
        self._world_T_camera = np.asarray(world_T_camera, np.float64).copy()
        self._scene.set_pose(self._camera_node, opengl_camera_pose(self._world_T_camera))

    def close(self) -> None:
        """Release the GL context; a later render creates a new one."""
        self._gl.close()

    def _place_occluders(self, occluders: Sequence[tuple[trimesh.Trimesh, np.ndarray]]) -> None:
        """Show this frame's occluders (meshes cached by identity), hide the others."""
        used = set()
        for mesh, world_T_mesh in occluders:
            check_pose(world_T_mesh, "occluder pose")
            key = id(mesh)
            if key not in self._occluder_nodes:
                node = self._scene.add(pyrender.Mesh.from_trimesh(mesh))
                self._occluder_nodes[key] = (mesh, node)  # holding the mesh keeps its id unique
                self._seg_map[node] = _OCCLUDER
            node = self._occluder_nodes[key][1]
            self._scene.set_pose(node, np.asarray(world_T_mesh, np.float64))
            used.add(key)
        for key, (_, node) in list(self._occluder_nodes.items()):
            node.mesh.is_visible = key in used
            # Callers that build new meshes every frame would otherwise grow the scene forever.
            if key not in used and len(self._occluder_nodes) > _MAX_CACHED_OCCLUDERS:
                self._scene.remove_node(node)
                del self._seg_map[node], self._occluder_nodes[key]

    def render(
        self,
        world_T_object: np.ndarray,
        occluders: Sequence[tuple[trimesh.Trimesh, np.ndarray]] = (),
    ) -> CameraReading:
        """One RGB-D frame with the object at `world_T_object`; `occluders` are (mesh, world_T_mesh)."""
        check_pose(world_T_object, "world_T_object")
        for node in self._object_nodes:
            self._scene.set_pose(node, np.asarray(world_T_object, np.float64))
        self._place_occluders(occluders)
        seg, depth = self._gl.get().render(
            self._scene, flags=pyrender.RenderFlags.SEG, seg_node_map=self._seg_map
        )
        code = seg[..., 0]
        depth = depth.astype(np.float32, copy=True)
        rgb = self._shade(depth, code)
        if self.depth_noise is not None:
            depth = self.depth_noise(depth)
        return CameraReading(
            rgb=rgb,
            depth=depth,
            intrinsics=self.intrinsics,
            world_T_camera=self.world_T_camera,
            mask=code >= _FIRST_OBJECT,
            name=self.name,
        )

    def _shade(self, depth: np.ndarray, code: np.ndarray) -> np.ndarray:
        """Lambertian colour from the palette and depth-map normals, (H, W, 3) uint8."""
        rgb = np.zeros((*depth.shape, 3), np.uint8)
        rows, cols = (
            np.nonzero((code > _NOTHING).any(axis=1))[0],
            np.nonzero((code > _NOTHING).any(axis=0))[0],
        )
        if len(rows) == 0:
            return rgb
        box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))  # only what was drawn
        z, c = depth[box], code[box]
        px, py = self._ray_x[box] * z, self._ray_y[box] * z
        # Tangents along image columns (u) and rows (v); their cross product is the normal.
        dxv, dxu = np.gradient(px)
        dyv, dyu = np.gradient(py)
        dzv, dzu = np.gradient(z)
        nx = dyu * dzv - dzu * dyv
        ny = dzu * dxv - dxu * dzv
        nz = dxu * dyv - dyu * dxv
        norm = np.sqrt(nx * nx + ny * ny + nz * nz)
        # Facing the camera (-z); silhouettes (depth jumps) fall back to a head-on normal.
        scale = np.where(nz > 0, -1.0, 1.0).astype(np.float32) / np.maximum(norm, 1e-20)
        nx, ny, nz = nx * scale, ny * scale, nz * scale
        jump = (np.abs(dzu) > 0.01) | (np.abs(dzv) > 0.01) | (norm < 1e-20)
        nx[jump], ny[jump], nz[jump] = 0.0, 0.0, -1.0
        kx, ky, kz = (self._world_T_camera[:3, :3].T @ _KEY_DIR_WORLD).astype(
            np.float32
        )  # camera frame
        light = (
            _AMBIENT
            + _KEY * np.maximum(nx * kx + ny * ky + nz * kz, 0.0)
            + _HEAD * np.maximum(-nz, 0.0)
        )
        rgb[box] = np.clip(self._palette[c] * (255.0 * light)[..., None], 0, 255).astype(np.uint8)
        return rgb
