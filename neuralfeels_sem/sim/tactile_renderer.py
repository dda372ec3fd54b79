"""TACTO-style DIGIT rendering: pyrender depth + material pass, then gel optics in numpy.

One pyrender pass (SEG flags) from the DIGIT's internal camera gives, per pixel, the
object's depth along +z and the material of the visible face. Where the object reaches
past the gel's outer surface (z < GEL_DISTANCE_M) the gel is pressed in. The indentation
map gets each material's micro-texture (evaluated at the object-frame 3D point under the
pixel, so the pattern moves with the object) and compliance (soft materials reach a bit
further and blur more), is smoothed like an elastomer, turned into surface normals and
shaded by three coloured LEDs (red, green, blue from different sides) as a change over
the sensor's own no-contact background image, plus Gaussian pixel noise.

Shading is done in numpy rather than with pyrender lights (gel_optics.py). Poses of a
pressing DIGIT are in digit_poses.py, the materials figure in
contact_sheet.py.

One DigitRenderer per finger: each holds its own background, noise stream and GL
context (created on the first render).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pyrender

from neuralfeels_sem.core.digit import (
    DIGIT_HEIGHT,
    DIGIT_INTRINSICS,
    DIGIT_WIDTH,
    GEL_DISTANCE_M,
)
from neuralfeels_sem.core.geometry import Intrinsics, check_pose, invert_pose
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.sim.backgrounds import resolve_background
from neuralfeels_sem.sim.felt_material import FeltMaterial
from neuralfeels_sem.sim.gel_optics import (
    MAX_RELIEF_M,
    SOFT_REACH_M,
    contact_crop,
    elastomer,
    indentation,
    led_shading,
    object_points,
    texture_relief,
)
from neuralfeels_sem.sim.pyrender_utils import decode_seg, seg_colour, split_by_material
from neuralfeels_sem.sim.textures import MicroTexture, compliance_for, specular_for, texture_for
from neuralfeels_sem.utils.offscreen import LazyOffscreen, intrinsics_camera, opengl_camera_pose

_NOISE_FRAMES, _NOISE_PAD = 8, 64  # noise bank: frames, extra rows/columns for random windows


@dataclass
class TactileRender:
    """One simulated DIGIT frame and its per-pixel ground truth (all 320 x 240)."""

    image: np.ndarray  # (320, 240, 3) uint8 RGB
    depth: np.ndarray  # (320, 240) float32, object depth along +z where in contact, 0 elsewhere
    contact_mask: np.ndarray  # (320, 240) bool
    material: np.ndarray  # (320, 240) int16 class index into obj.class_names, -1 = none / ignore

    @property
    def in_contact(self) -> bool:
        return bool(self.contact_mask.any())


class DigitRenderer:
    """Renders one DIGIT touching one MaterialObject.

    Args:
        obj: the object (mesh in metres, per-face material labels).
        background: None = procedural (by `seed`), a path to an empty DIGIT frame (or a
            folder of them; the `seed`-th is used), or a (320, 240, 3) uint8 RGB array.
        noise_std: per-pixel Gaussian noise in grey levels.
        seed: background and noise seed.
        texture_scale: multiplies every material's micro-texture relief (0 = smooth).
        compliance: per-material-name compliance 0..1 overriding the defaults
            (fabric 1, plastic 0.15, wood 0.05, metal 0).
        light_gain: grey levels per unit change of n . l (shading contrast).
        press_gain: grey levels added at full press (the thinned gel looks brighter).
        blur_px: elastomer smoothing (Gaussian sigma, pixels) of a rigid contact.
        soft_blur_px: smoothing of a fully compliant contact.
        smooth_px: smoothing (Gaussian sigma, pixels) of the object's depth before shading,
            so triangle facets of the mesh do not show as flat shaded patches (0 = off;
            ground-truth depth is never smoothed).
        ignored_faces: how faces scoring ignores press (sim/felt_material.py): `nearest`
            (the nearest labelled face's material) or `generic` (a texture of no material).
    """

    def __init__(
        self,
        obj: MaterialObject,
        background: np.ndarray | str | Path | None = None,
        noise_std: float = 2.0,
        seed: int = 0,
        texture_scale: float = 1.0,
        compliance: dict[str, float] | None = None,
        light_gain: float = 200.0,
        press_gain: float = 30.0,
        blur_px: float = 0.8,
        soft_blur_px: float = 1.6,
        smooth_px: float = 5.0,
        ignored_faces: str = "nearest",
    ) -> None:
        if (
            noise_std < 0
            or texture_scale < 0
            or light_gain < 0
            or blur_px <= 0
            or smooth_px < 0
            or soft_blur_px < blur_px
        ):
            raise ValueError(
                "need noise_std >= 0, texture_scale >= 0, light_gain >= 0, 0 < blur_px <= soft_blur_px; got "
                f"{noise_std}, {texture_scale}, {light_gain}, {blur_px}, {soft_blur_px}"
            )
        self.obj = obj
        self.noise_std = float(noise_std)
        self.light_gain = float(light_gain)
        self.press_gain = float(press_gain)
        self.blur_px, self.soft_blur_px = float(blur_px), float(soft_blur_px)
        self.smooth_px = float(smooth_px)
        self._background_spec = background
        self._background: np.ndarray | None = None
        self._seed = seed
        self._rng = np.random.default_rng(seed)
        self._noise_bank: np.ndarray | None = None
        self._materials(obj.class_names, seed, texture_scale, compliance)
        self._build_scene(obj)
        self._felt = FeltMaterial(obj, ignored_faces)  # how ignored faces press

    def _materials(
        self,
        names: list[str],
        seed: int,
        texture_scale: float,
        compliance: dict[str, float] | None,
    ) -> None:
        """Per-label textures and lookup tables; index len(names) stands for IGNORE faces."""
        self._textures: list[MicroTexture] = [texture_for(n, seed, texture_scale) for n in names]
        self._generic = texture_for("", seed, texture_scale)
        self._compliance = np.array(
            [compliance_for(n, compliance) for n in names] + [compliance_for("")], np.float32
        )
        self._specular = np.array([specular_for(n) for n in names] + [0.0], np.float32)
        self._reach = (
            GEL_DISTANCE_M + MAX_RELIEF_M * texture_scale + SOFT_REACH_M * self._compliance
        )

    def _build_scene(self, obj: MaterialObject) -> None:
        """The pyrender scene in the sensor frame: the camera is fixed, the object moves."""
        self._scene = pyrender.Scene(bg_color=[0, 0, 0, 0], ambient_light=[0, 0, 0])
        self._nodes: list[pyrender.Node] = []
        self._seg_map: dict[pyrender.Node, np.ndarray] = {}
        for label, sub in split_by_material(obj):
            node = self._scene.add(pyrender.Mesh.from_trimesh(sub, smooth=True))
            self._nodes.append(node)
            self._seg_map[node] = seg_colour(label)
        # Far plane just past the deepest reach: the rasteriser skips the rest of the object.
        self._znear, self._zfar = 1e-3, float(self._reach.max()) + 1e-3
        camera = intrinsics_camera(DIGIT_INTRINSICS, znear=self._znear, zfar=self._zfar)
        # For culling: a triangle can only reach the view volume if one of its vertices is
        # within one (longest) edge length of it.
        self._vertices = np.asarray(obj.mesh.vertices, np.float64)
        self._max_edge = float(obj.mesh.edges_unique_length.max()) if len(obj.mesh.faces) else 0.0
        self._scene.add(camera, pose=opengl_camera_pose(np.eye(4)))
        self._gl = LazyOffscreen(DIGIT_WIDTH, DIGIT_HEIGHT)

    @property
    def intrinsics(self) -> Intrinsics:
        return DIGIT_INTRINSICS

    @property
    def background_image(self) -> np.ndarray:
        """The no-contact frame (320, 240, 3) uint8 RGB, without noise."""
        if self._background is None:  # loaded lazily: a path means file I/O
            self._background = resolve_background(self._background_spec, self._seed)
        return self._background

    def close(self) -> None:
        """Release the GL context; a later render creates a new one."""
        self._gl.close()

    # ------------------------------------------------------------------ rendering
    def render_geometry(
        self, world_T_object: np.ndarray, world_T_sensor: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Raw pass: object depth along +z (0 where nothing within reach) and labels (int16)."""
        check_pose(world_T_object, "world_T_object")
        check_pose(world_T_sensor, "world_T_sensor")
        sensor_T_object = invert_pose(world_T_sensor) @ world_T_object
        if not self._may_be_visible(sensor_T_object):
            return np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH), np.float32), np.full(
                (DIGIT_HEIGHT, DIGIT_WIDTH), IGNORE, np.int16
            )
        for node in self._nodes:
            self._scene.set_pose(node, sensor_T_object)
        seg, depth = self._gl.get().render(
            self._scene, flags=pyrender.RenderFlags.SEG, seg_node_map=self._seg_map
        )
        return depth.astype(np.float32, copy=False), decode_seg(seg)

    def _may_be_visible(self, sensor_T_object: np.ndarray) -> bool:
        """Conservative test: could any triangle reach the (short) view volume of the gel?

        Most fingers are out of contact most of the time; this skips their GL pass.
        """
        points = self._vertices @ sensor_T_object[:3, :3].T + sensor_T_object[:3, 3]
        margin = self._max_edge
        z = points[:, 2]
        k = DIGIT_INTRINSICS
        half_x = (self._zfar + margin) * (k.cx + 1.0) / k.fx + margin
        half_y = (self._zfar + margin) * (k.cy + 1.0) / k.fy + margin
        inside = (
            (z > self._znear - margin)
            & (z < self._zfar + margin)
            & (np.abs(points[:, 0]) < half_x)
            & (np.abs(points[:, 1]) < half_y)
        )
        return bool(inside.any())

    def render(self, world_T_object: np.ndarray, world_T_sensor: np.ndarray) -> TactileRender:
        change, truth = self.render_change(world_T_object, world_T_sensor)
        image = self.background_image.astype(np.float32) + change
        if self.noise_std > 0:
            image += self._noise()
        truth.image = np.clip(image, 0, 255).astype(np.uint8)
        return truth

    def render_change(
        self, world_T_object: np.ndarray, world_T_sensor: np.ndarray
    ) -> tuple[np.ndarray, TactileRender]:
        """The gel's shading as a change over any background ((320, 240, 3) float32 grey
        levels, no noise) and the frame's ground truth (its `image` is the background).

        `render` is background + change + noise, clipped: training data for the tactile
        depth network composes the same sum over many backgrounds from one render.
        """
        depth, labels = self.render_geometry(world_T_object, world_T_sensor)
        hit = depth > 0
        contact = hit & (depth < GEL_DISTANCE_M)
        gt_depth = np.where(contact, depth, 0.0).astype(np.float32)
        gt_material = np.where(contact, labels, IGNORE).astype(np.int16)

        change = np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH, 3), np.float32)
        object_T_sensor = invert_pose(world_T_object) @ world_T_sensor
        felt = self._felt(labels, depth, hit, object_T_sensor)
        # Pixels the gel can feel: soft materials and texture relief reach past the surface.
        reach = self._reach[np.where(felt == IGNORE, len(self._textures), felt)]
        near = hit & (depth < reach)
        if near.any():
            self._shade(change, depth, felt, near, object_T_sensor)
        truth = TactileRender(
            image=self.background_image, depth=gt_depth, contact_mask=contact, material=gt_material
        )
        return change, truth

    def _noise(self) -> np.ndarray:
        """A fresh (320, 240, 3) Gaussian noise frame: a random window of a lazily drawn bank.

        Drawing 230k normals per frame costs more than the rest of a no-contact frame;
        random windows into 8 larger frames give i.i.d. pixels and ~10^5 distinct frames.
        """
        if self._noise_bank is None:
            shape = (_NOISE_FRAMES, DIGIT_HEIGHT + _NOISE_PAD, DIGIT_WIDTH + _NOISE_PAD, 3)
            self._noise_bank = self._rng.standard_normal(shape, dtype=np.float32) * np.float32(
                self.noise_std
            )
        i, dy, dx = self._rng.integers((_NOISE_FRAMES, _NOISE_PAD + 1, _NOISE_PAD + 1))
        return self._noise_bank[i, dy : dy + DIGIT_HEIGHT, dx : dx + DIGIT_WIDTH]

    def _shade(
        self,
        image: np.ndarray,
        depth: np.ndarray,
        labels: np.ndarray,
        near: np.ndarray,
        object_T_sensor: np.ndarray,
    ) -> None:
        """Add the pressed gel's shading to `image` in place, on a crop around the contact."""
        pad = int(np.ceil(3 * self.soft_blur_px)) + 2
        r0, r1, c0, c1 = contact_crop(near, pad)
        d = depth[r0:r1, c0:c1]
        m = near[r0:r1, c0:c1]
        lab = labels[r0:r1, c0:c1].astype(np.int64)
        lut = np.where(lab == IGNORE, len(self._textures), lab)

        # Object-frame 3D points under the near pixels, for the micro-texture.
        v, u = np.nonzero(m)
        pts_o = object_points(v, u, d[v, u], r0, c0, object_T_sensor)
        # The touched surface faces the camera: its normal is the sensor's -z in the object frame.
        normal_o = -object_T_sensor[:3, 2]
        lut_vu = lut[v, u]
        relief = texture_relief(self._textures, self._generic, pts_o, normal_o, lut_vu)

        comp = np.zeros(d.shape, np.float32)
        comp[v, u] = self._compliance[lut_vu]
        far = np.float32(self._reach.max() + 1e-3)
        pen = indentation(d, m, v, u, relief, comp, self.smooth_px, far)
        h = elastomer(pen, comp, self.blur_px, self.soft_blur_px)
        gloss = np.full(d.shape, 0.15, np.float32)
        if self._specular.any():
            spec = np.zeros(d.shape, np.float32)
            spec[v, u] = self._specular[lut_vu]
            gloss += cv2.GaussianBlur(spec, (0, 0), self.soft_blur_px)
        image[r0:r1, c0:c1] += led_shading(h, gloss, self.light_gain, self.press_gain)
