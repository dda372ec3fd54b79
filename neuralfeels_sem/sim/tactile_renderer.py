"""TACTO-style DIGIT rendering: pyrender depth + material pass, then gel optics in numpy.

One pyrender pass (SEG flags) from the DIGIT's internal camera gives, per pixel, the
object's depth along +z and the material of the visible face. Where the object reaches
past the gel's outer surface (z < GEL_DISTANCE_M) the gel is pressed in. The indentation
map gets each material's micro-texture (evaluated at the object-frame 3D point under the
pixel, so the pattern moves with the object) and compliance (soft materials reach a bit
further and blur more), is smoothed like an elastomer, turned into surface normals and
shaded by three coloured LEDs (red, green, blue from different sides) as a change over
the sensor's own no-contact background image, plus Gaussian pixel noise.

Shading is done in numpy rather than with pyrender lights: the gel is a height field
seen head-on, so Lambertian + Blinn-Phong on its normals is exact for that model and
much cheaper than rendering a deformed gel mesh.

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
    GEL_WIDTH_M,
    MAX_PENETRATION_M,
)
from neuralfeels_sem.core.geometry import Intrinsics, check_pose, invert_pose, rotation_matrix
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.sim.backgrounds import resolve_background
from neuralfeels_sem.sim.pyrender_utils import (
    LazyOffscreen,
    decode_seg,
    intrinsics_camera,
    opengl_camera_pose,
    seg_colour,
    split_by_material,
)
from neuralfeels_sem.sim.textures import MicroTexture, compliance_for, specular_for, texture_for

MAX_RELIEF_M = 0.1e-3  # above every texture's highest relief (fabric threads + fuzz: ~60 um)
_NOISE_FRAMES, _NOISE_PAD = 8, 64  # noise bank: frames, extra rows/columns for random windows
PIXEL_M = GEL_WIDTH_M / DIGIT_WIDTH  # gel-plane size of one pixel (75 um)
SOFT_REACH_M = (
    0.35e-3  # how much further a fully compliant surface (fibres, fuzz) reaches into the gel
)
# LEDs: direction from the gel toward each light in the sensor frame (+x = image right,
# +y = image down, -z = back toward the camera) and its RGB colour.
_LIGHT_DIRS = np.array([[-1.0, -0.15, -0.55], [1.0, 0.1, -0.55], [0.05, 1.0, -0.55]], np.float32)
_LIGHT_DIRS /= np.linalg.norm(_LIGHT_DIRS, axis=1, keepdims=True)
_LIGHT_RGB = np.array([[1.0, 0.12, 0.15], [0.1, 1.0, 0.15], [0.12, 0.2, 1.0]], np.float32)
# Blinn-Phong half vectors between each light and the view direction (-z, toward the camera).
_HALF_DIRS = _LIGHT_DIRS + np.array([0.0, 0.0, -1.0], np.float32)
_HALF_DIRS /= np.linalg.norm(_HALF_DIRS, axis=1, keepdims=True)


def _pow32(x: np.ndarray) -> np.ndarray:
    """x ** 32 by repeated squaring (much faster than a float power)."""
    for _ in range(5):
        x = x * x
    return x


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
        names = obj.class_names
        self._textures: list[MicroTexture] = [texture_for(n, seed, texture_scale) for n in names]
        self._generic = texture_for("", seed, texture_scale)
        # Per-label lookup tables; index len(names) stands for IGNORE faces.
        self._compliance = np.array(
            [compliance_for(n, compliance) for n in names] + [compliance_for("")], np.float32
        )
        self._specular = np.array([specular_for(n) for n in names] + [0.0], np.float32)
        self._reach = (
            GEL_DISTANCE_M + MAX_RELIEF_M * texture_scale + SOFT_REACH_M * self._compliance
        )

        self._scene = pyrender.Scene(bg_color=[0, 0, 0, 0], ambient_light=[0, 0, 0])
        self._nodes: list[pyrender.Node] = []
        self._seg_map: dict[pyrender.Node, np.ndarray] = {}
        for label, sub in split_by_material(obj):
            node = self._scene.add(pyrender.Mesh.from_trimesh(sub, smooth=True))
            self._nodes.append(node)
            self._seg_map[node] = seg_colour(label)
        # The scene is in the sensor frame: the camera is fixed, the object moves.
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
        depth, labels = self.render_geometry(world_T_object, world_T_sensor)
        hit = depth > 0
        contact = hit & (depth < GEL_DISTANCE_M)
        gt_depth = np.where(contact, depth, 0.0).astype(np.float32)
        gt_material = np.where(contact, labels, IGNORE).astype(np.int16)

        image = self.background_image.astype(np.float32)
        # Pixels the gel can feel: soft materials and texture relief reach past the surface.
        reach = self._reach[np.where(labels == IGNORE, len(self._textures), labels)]
        near = hit & (depth < reach)
        if near.any():
            object_T_sensor = invert_pose(world_T_object) @ world_T_sensor
            self._shade(image, depth, labels, near, object_T_sensor)
        if self.noise_std > 0:
            image += self._noise()
        out = np.clip(image, 0, 255).astype(np.uint8)
        return TactileRender(image=out, depth=gt_depth, contact_mask=contact, material=gt_material)

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
        rows, cols = np.nonzero(near)
        r0, r1 = max(rows.min() - pad, 0), min(rows.max() + pad + 1, DIGIT_HEIGHT)
        c0, c1 = max(cols.min() - pad, 0), min(cols.max() + pad + 1, DIGIT_WIDTH)
        d = depth[r0:r1, c0:c1]
        m = near[r0:r1, c0:c1]
        lab = labels[r0:r1, c0:c1].astype(np.int64)
        lut = np.where(lab == IGNORE, len(self._textures), lab)

        # Object-frame 3D points under the near pixels, for the micro-texture.
        v, u = np.nonzero(m)
        z = d[v, u]
        uf, vf = u.astype(np.float32), v.astype(np.float32)
        k = DIGIT_INTRINSICS
        rot = object_T_sensor[:3, :3].astype(np.float32)
        xs, ys = (
            (uf + np.float32(c0 - k.cx)) * (z / np.float32(k.fx)),
            (vf + np.float32(r0 - k.cy)) * (z / np.float32(k.fy)),
        )
        pts_o = np.empty((len(z), 3), np.float32)
        for i in range(3):
            pts_o[:, i] = (
                rot[i, 0] * xs + rot[i, 1] * ys + rot[i, 2] * z + np.float32(object_T_sensor[i, 3])
            )
        # The touched surface faces the camera: its normal is the sensor's -z in the object frame.
        normal_o = -object_T_sensor[:3, 2]
        lut_vu = lut[v, u]
        present = np.nonzero(np.bincount(lut_vu, minlength=len(self._textures) + 1))[0]
        relief = np.empty(len(z), np.float32)
        for idx in present:
            sel = slice(None) if len(present) == 1 else lut_vu == idx
            tex = self._textures[idx] if idx < len(self._textures) else self._generic
            relief[sel] = tex.height(pts_o[sel], normal_o)

        # Indentation of the gel: texture stands proud of the surface, soft surfaces reach further.
        comp = np.zeros(d.shape, np.float32)
        comp[v, u] = self._compliance[lut_vu]
        pen = np.zeros(d.shape, np.float32)
        if self.smooth_px > 0:
            # Missing depth (beyond the far plane) counts as far away, never as contact.
            far = np.float32(self._reach.max() + 1e-3)
            z = cv2.GaussianBlur(np.where(d > 0, d, far), (0, 0), self.smooth_px)[v, u]
        pen[v, u] = relief - z
        pen += GEL_DISTANCE_M + SOFT_REACH_M * comp
        pen[~m] = 0.0
        np.clip(pen, 0.0, MAX_PENETRATION_M, out=pen)

        # Elastomer smoothing, stronger where the material is soft.
        w = cv2.GaussianBlur(comp, (0, 0), self.soft_blur_px)
        h = cv2.GaussianBlur(pen, (0, 0), self.blur_px)
        h += w * (cv2.GaussianBlur(pen, (0, 0), self.soft_blur_px) - h)
        gloss = np.full(d.shape, 0.15, np.float32)
        if self._specular.any():
            spec = np.zeros(d.shape, np.float32)
            spec[v, u] = self._specular[lut_vu]
            gloss += cv2.GaussianBlur(spec, (0, 0), self.soft_blur_px)

        # Normals of the pressed gel (height toward the camera) in the sensor frame:
        # n = (-gx, -gy, -1) / |.|, written out per component (small arrays, many pixels).
        # Central differences (one-sided at the crop border, where h is 0 anyway).
        gx = cv2.Sobel(
            h, cv2.CV_32F, 1, 0, ksize=1, scale=0.5 / PIXEL_M, borderType=cv2.BORDER_REPLICATE
        )
        gy = cv2.Sobel(
            h, cv2.CV_32F, 0, 1, ksize=1, scale=0.5 / PIXEL_M, borderType=cv2.BORDER_REPLICATE
        )
        nz = -1.0 / np.sqrt(gx * gx + gy * gy + 1.0)
        nx, ny = gx * nz, gy * nz
        response = np.empty((*h.shape, 3), np.float32)
        for i, ((lx, ly, lz), (hx, hy, hz)) in enumerate(zip(_LIGHT_DIRS, _HALF_DIRS)):
            lambert = nx * lx + ny * ly + (nz + 1.0) * lz  # n.l minus its flat-gel value (-lz)
            cos_h = np.maximum(nx * hx + ny * hy + nz * hz, 0.0)
            response[..., i] = lambert + gloss * (_pow32(cos_h) - _pow32(-hz))
        shading = cv2.transform(response, self.light_gain * _LIGHT_RGB.T)  # lights -> RGB
        shading += ((self.press_gain / MAX_PENETRATION_M) * h)[..., None]
        image[r0:r1, c0:c1] += shading


def pose_pressing(
    point: np.ndarray, normal: np.ndarray, press_m: float, roll_rad: float = 0.0
) -> np.ndarray:
    """world_T_sensor of a DIGIT whose gel centre is pressed `press_m` into a surface.

    `point` and `normal` (outward) are the touched surface point and its normal in the
    world frame; a negative `press_m` leaves a gap. `roll_rad` turns the sensor about
    its optical axis.
    """
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    z = -n
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    x, y = c * x + s * y, -s * x + c * y
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, y, z
    pose[:3, 3] = np.asarray(point, np.float64) + n * (GEL_DISTANCE_M - press_m)
    return pose


def pose_pressing_edge(
    point: np.ndarray,
    normal: np.ndarray,
    press_m: float,
    gel_point: tuple[float, float],
    tilt_rad: float,
    roll_rad: float = 0.0,
) -> np.ndarray:
    """world_T_sensor of a DIGIT tilted so an off-centre gel point presses `press_m` deepest.

    `gel_point` = (x, y) on the gel in metres from its centre (sensor frame). The sensor is
    turned by `tilt_rad` about the gel-plane axis through that point perpendicular to its
    offset, lifting the gel centre off the surface: the imprint is a strip along the
    sensor edge, as a tilted fingertip pad makes on a narrow object.
    """
    offset = np.array([gel_point[0], gel_point[1], 0.0])
    if np.linalg.norm(offset) < 1e-9:
        raise ValueError("gel_point must be off the gel centre for an edge press")
    pose = pose_pressing(point, normal, press_m, roll_rad)
    rotation = pose[:3, :3]
    pivot = pose[:3, 3] + rotation @ [0.0, 0.0, GEL_DISTANCE_M]  # the pressed gel point
    pose[:3, 3] -= rotation @ offset  # the gel point, not the centre, sits on `point`
    axis = rotation @ np.array([-offset[1], offset[0], 0.0])
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    best = None
    for sign in (1.0, -1.0):
        turn = rotation_matrix(axis, sign * tilt_rad)
        candidate = np.eye(4)
        candidate[:3, :3] = turn @ rotation
        candidate[:3, 3] = pivot + turn @ (pose[:3, 3] - pivot)
        centre = candidate[:3, :3] @ [0.0, 0.0, GEL_DISTANCE_M] + candidate[:3, 3]
        lift = float(n @ centre)  # the gel centre must move away from the surface
        if best is None or lift > best[0]:
            best = (lift, candidate)
    return best[1]


def contact_sheet(
    path: str | Path,
    materials: tuple[str, ...] = tuple(DEFAULT_MATERIALS),
    radius_m: float = 0.025,
    press_m: float = 1.0e-3,
    seed: int = 0,
    side_views: tuple[str, ...] = ("wood",),
) -> Path:
    """Write a PNG: the no-contact background, then each material pressed into a sphere.

    Each material is pressed at the pole (object z, wood's end grain); the materials in
    `side_views` are pressed on the equator too, where the wood runs along its grain.
    Draws docs/images/tactile_materials.png (shown in docs/simulation.md); also to eyeball realism.
    """
    import trimesh  # only this figure needs a primitive mesh

    mesh = trimesh.creation.icosphere(subdivisions=5, radius=radius_m)
    presses = {
        "": pose_pressing(np.array([0.0, 0.0, radius_m]), np.array([0.0, 0.0, 1.0]), press_m),
        " (side)": pose_pressing(
            np.array([radius_m, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), press_m
        ),
    }
    panels, names = [], ["background"]
    for i, name in enumerate(materials):
        obj = MaterialObject(name, mesh, np.full(len(mesh.faces), i), materials)
        renderer = DigitRenderer(obj, seed=seed)
        if not panels:
            panels.append(renderer.background_image)
        for suffix, world_T_sensor in presses.items():
            if suffix and name not in side_views:
                continue
            panels.append(renderer.render(np.eye(4), world_T_sensor).image)
            names.append(name + suffix)
        renderer.close()
    sheet = np.concatenate(
        [np.pad(p, ((0, 0), (2, 2), (0, 0)), constant_values=255) for p in panels], axis=1
    )
    sheet = np.pad(sheet, ((28, 0), (0, 0), (0, 0)), constant_values=255)
    for i, name in enumerate(names):
        cv2.putText(
            sheet, name, (i * 244 + 8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA
        )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    return path
