"""Material micro-textures: exact properties of each relief, and that they tell materials apart in images."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import trimesh
from scipy import ndimage

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.digit_poses import pose_pressing
from neuralfeels_sem.sim.tactile_renderer import DigitRenderer
from neuralfeels_sem.sim.textures import (
    FabricTexture,
    MetalTexture,
    MicroTexture,
    PlasticTexture,
    WoodTexture,
    compliance_for,
    texture_for,
)

MATERIALS = tuple(DEFAULT_MATERIALS)


def _points(count: int = 4000, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.02, 0.02, (count, 3)).astype(np.float32)


def test_lookup_by_name_is_case_insensitive_with_a_generic_fallback() -> None:
    assert isinstance(texture_for("Fabric"), FabricTexture)
    assert isinstance(texture_for("wood"), WoodTexture)
    assert isinstance(texture_for("METAL"), MetalTexture)
    assert isinstance(texture_for("plastic"), PlasticTexture)
    generic = texture_for("glass")
    assert type(generic) is MicroTexture
    assert 0 < generic.height(_points()).std() < 2e-6  # smooth, but not perfectly flat


def test_heights_are_deterministic_scaled_and_seeded() -> None:
    pts = _points()
    for name in MATERIALS:
        a = texture_for(name, seed=3).height(pts)
        np.testing.assert_array_equal(a, texture_for(name, seed=3).height(pts))
        np.testing.assert_allclose(
            texture_for(name, seed=3, scale=2.0).height(pts), 2 * a, rtol=1e-5, atol=1e-12
        )
        assert not np.allclose(a, texture_for(name, seed=4).height(pts))
        assert not texture_for(name, scale=0.0).height(pts).any()
        assert a.dtype == np.float32 and a.shape == (len(pts),)
    with pytest.raises(ValueError):
        texture_for("metal").height(np.zeros((5, 2)))
    with pytest.raises(ValueError):
        texture_for("metal", scale=-1.0)


def test_relief_amplitudes_are_ordered_like_real_surfaces() -> None:
    pts = _points()
    std = {
        name: float(texture_for(name).height(pts, np.array([0.0, 0.0, 1.0])).std())
        for name in MATERIALS
    }
    # Rough (fabric, wood) versus smooth (plastic, metal) surfaces.
    assert min(std["fabric"], std["wood"]) > 1.5 * max(std["plastic"], std["metal"])
    assert min(std["plastic"], std["metal"]) > 1e-6
    assert std["fabric"] < 40e-6  # tens of micrometres at most: plausible, not a corrugated sheet


def test_metal_brush_lines_run_along_object_x() -> None:
    tex = MetalTexture(seed=1)
    pts = _points()
    shifted = pts + np.array([0.007, 0.0, 0.0], np.float32)
    np.testing.assert_allclose(tex.height(shifted), tex.height(pts), atol=1e-9)
    assert (
        np.abs(tex.height(pts + np.array([0.0, 0.007, 0.0], np.float32)) - tex.height(pts)).max()
        > 1e-6
    )


def test_fabric_weave_repeats_every_two_threads() -> None:
    tex = FabricTexture(seed=2)
    tex.fuzz_m = 0.0  # the weave alone is exactly periodic
    normal = np.array([0.0, 0.0, 1.0])
    pts = _points()
    c, s = np.cos(tex._angle), np.sin(tex._angle)
    for step in (np.array([c, s, 0.0]), np.array([-s, c, 0.0])):
        moved = pts + (2 * tex.period_m * step).astype(np.float32)
        np.testing.assert_allclose(tex.height(moved, normal), tex.height(pts, normal), atol=2e-7)
    half = pts + (tex.period_m * np.array([c, s, 0.0])).astype(np.float32)
    assert (
        np.abs(tex.height(half, normal) - tex.height(pts, normal)).mean() > 5e-6
    )  # over/under swaps


def test_metal_brushing_is_finer_and_fainter_than_wood_fibres() -> None:
    metal = MetalTexture(seed=0)
    assert max(metal.line_wavelength_m) < 0.4e-3 and min(metal.line_wavelength_m) >= 0.15e-3
    # The finest lines span two DIGIT pixels (75 um) or more: no aliasing in the render.
    assert metal.line_height_m <= WoodTexture.fibre_height_m / 2
    heights = metal.height(_points(20000))
    assert 1e-6 < heights.std() < 4e-6


def test_wood_grain_is_anisotropic_along_the_fibres() -> None:
    tex = WoodTexture(seed=0)
    tex.pore_depth_m = 0.0  # rings and fibres alone are straight along the grain
    t = np.linspace(0, 0.003, 200, dtype=np.float32)
    start = np.array([0.012, 0.004, 0.0], np.float32)
    along_z = tex.height(start + t[:, None] * np.array([0, 0, 1], np.float32))
    along_x = tex.height(start + t[:, None] * np.array([1, 0, 0], np.float32))
    assert along_z.std() < 0.02 * along_x.std()


def _ring_tangent_patch(tex: WoodTexture, size_m: float = 0.008) -> np.ndarray:
    """Points on a cylinder about the pith: a face running along the growth rings."""
    radius = 5.3 * tex.ring_period_m  # early wood of the sixth ring
    angle, z = np.meshgrid(np.linspace(0, size_m / radius, 120), np.linspace(0, size_m, 120))
    cx, cy = tex._centre
    return (
        np.stack([cx + radius * np.cos(angle), cy + radius * np.sin(angle), z], axis=-1)
        .reshape(-1, 3)
        .astype(np.float32)
    )


def test_wood_pores_are_pits_elongated_along_the_grain_on_every_cut() -> None:
    tex = WoodTexture(seed=0)
    # On a face along the rings, rings and fibres are parallel lines (like brushed
    # metal); the pores are what still marks it as wood.
    patch = _ring_tangent_patch(tex)
    pores = tex.pores(patch)
    assert pores.max() == 0.0 and pores.min() < -0.9
    assert 0.03 < (pores < 0).mean() < 0.3
    # Each pit is a dash along the grain: 0.7-1.5 mm long, 0.2-0.3 mm wide.
    pits, count = ndimage.label(pores.reshape(120, 120) < 0)  # rows: z, columns: across
    spans = np.array(
        [(s[0].stop - s[0].start, s[1].stop - s[1].start) for s in ndimage.find_objects(pits)]
    )
    assert count >= 5
    assert np.median(spans[:, 0] / spans[:, 1]) > 2.5
    tex.pore_depth_m = 0.0
    without = tex.height(patch)
    tex.pore_depth_m = WoodTexture.pore_depth_m
    np.testing.assert_allclose(
        tex.height(patch) - without, WoodTexture.pore_depth_m * pores, atol=1e-9
    )
    # Pores are denser in the early wood than in the late wood of a ring.
    cut = _points(40000, seed=3)
    phase = tex._ring_phase(cut)
    holes = tex.pores(cut) < 0
    assert holes[phase < 0.3].mean() > 1.5 * holes[phase > 0.6].mean()


def test_plastic_stipple_is_sparse_bumps() -> None:
    heights = PlasticTexture(seed=0).height(_points(20000))
    assert heights.min() >= 0.0
    assert 0.05 < (heights > 0).mean() < 0.35


def test_compliance_defaults_overrides_and_errors() -> None:
    assert compliance_for("fabric") == 1.0 and compliance_for("metal") == 0.0
    assert compliance_for("Wood", {"wood": 0.4}) == 0.4
    assert compliance_for("foam") == pytest.approx(0.1)
    with pytest.raises(ConfigError, match="sensor.tactile.compliance.fabric"):
        compliance_for("fabric", {"fabric": 2.0})


# ------------------------------------------------------------------ in rendered images
def _box(material: str) -> MaterialObject:
    mesh = trimesh.creation.box(extents=(0.08, 0.08, 0.02))
    return MaterialObject(
        material, mesh, np.full(len(mesh.faces), MATERIALS.index(material)), MATERIALS
    )


def test_texture_is_fixed_to_the_object_and_moves_with_it() -> None:
    """Slide the sensor over a flat face by exactly 12 pixels: the pattern shifts 12 columns."""
    press = 0.8e-3
    renderer = DigitRenderer(_box("fabric"), noise_std=0.0)
    top = np.array([0.0, 0.0, 0.01])
    pose = pose_pressing(top, np.array([0.0, 0.0, 1.0]), press)
    shift_px = 12
    moved = pose.copy()
    moved[:3, 3] += pose[:3, 0] * shift_px * (GEL_DISTANCE_M - press) / DIGIT_INTRINSICS.fx
    a = renderer.render(np.eye(4), pose).image.astype(float)
    b = renderer.render(np.eye(4), moved).image.astype(float)
    interior = (slice(60, 260), slice(40, 180))
    diff_bg = a - renderer.background_image  # the background does not move; the texture does
    diff_b = b - renderer.background_image
    aligned = np.abs(
        diff_bg[interior[0], interior[1].start + shift_px : interior[1].stop + shift_px]
        - diff_b[interior]
    ).mean()
    unaligned = np.abs(diff_bg[interior] - diff_b[interior]).mean()
    assert aligned < 0.15 * unaligned
    renderer.close()


def _log_radial_spectrum(image: np.ndarray, background: np.ndarray) -> np.ndarray:
    grey = (image.astype(np.float32) - background.astype(np.float32)).mean(axis=2)
    win = grey[112:208, 72:168]
    win = (win - cv2.GaussianBlur(win, (0, 0), 6)) * np.outer(np.hanning(96), np.hanning(96))
    power = np.abs(np.fft.fftshift(np.fft.fft2(win))) ** 2
    fy, fx = np.mgrid[-48:48, -48:48]
    radius = np.hypot(fx, fy)
    edges = [2, 4, 6, 9, 13, 18, 25, 34, 48]
    energy = np.array(
        [power[(radius >= lo) & (radius < hi)].mean() for lo, hi in zip(edges[:-1], edges[1:])]
    )
    return np.log(energy / energy.sum())


def test_materials_give_statistically_different_images_at_equal_press() -> None:
    radius = 0.06
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    point = np.array([0.0, 0.0, radius])
    pose = pose_pressing(point, np.array([0.0, 0.0, 1.0]), 1e-3)
    spectra, energy = {}, {}
    for i, name in enumerate(MATERIALS):
        renderer = DigitRenderer(
            MaterialObject(name, mesh, np.full(len(mesh.faces), i), MATERIALS), noise_std=0.0
        )
        out = renderer.render(np.eye(4), pose)
        spectra[name] = _log_radial_spectrum(out.image, renderer.background_image)
        interior = cv2.erode(out.contact_mask.astype(np.uint8), np.ones((31, 31))) > 0
        grey = out.image.astype(np.float32).mean(axis=2)
        energy[name] = float((grey - cv2.GaussianBlur(grey, (0, 0), 4))[interior].std())
        renderer.close()
    for i, a in enumerate(MATERIALS):
        for b in MATERIALS[i + 1 :]:
            assert np.abs(spectra[a] - spectra[b]).sum() > 2.0, (a, b)
    # Fabric's weave puts most energy at ~1 mm periods; wood's fibres and rings the most at fine scales.
    assert max(MATERIALS, key=lambda m: spectra[m][1:3].sum()) == "fabric"
    assert max(MATERIALS, key=lambda m: spectra[m][5:7].sum()) == "wood"
    assert min(energy.values()) > 0.5  # every texture is visible through the gel


def test_no_texture_rises_above_the_renderers_reach_margin() -> None:
    from neuralfeels_sem.sim.gel_optics import MAX_RELIEF_M

    pts = np.random.default_rng(5).uniform(-0.03, 0.03, (100000, 3)).astype(np.float32)
    for name in (*MATERIALS, "unknown"):
        for normal in (
            np.array([0.0, 0.0, 1.0]),
            np.array([0.6, 0.0, 0.8]),
            np.array([0.3, 0.5, 0.81]),
        ):
            assert texture_for(name, seed=1).height(pts, normal).max() < MAX_RELIEF_M
