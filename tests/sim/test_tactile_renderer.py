"""DigitRenderer: geometry round trips, contact patch size, material map, backgrounds, realism checks."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.geometry import (
    backproject,
    invert_pose,
    rotation_matrix,
    transform_points,
)
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.perception.contact import edge_share
from neuralfeels_sem.sim.backgrounds import (
    load_background,
    procedural_background,
    resolve_background,
)
from neuralfeels_sem.sim.contact_sheet import contact_sheet
from neuralfeels_sem.sim.digit_poses import pose_pressing, pose_pressing_edge
from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

MATERIALS = tuple(DEFAULT_MATERIALS)
RADIUS = 0.025


def _sphere(labels_fn=None, subdivisions: int = 5) -> MaterialObject:
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=RADIUS)
    labels = (
        np.zeros(len(mesh.faces), int) if labels_fn is None else labels_fn(mesh.triangles_center)
    )
    return MaterialObject("sphere", mesh, labels, MATERIALS)


def _half_sphere_labels(centres: np.ndarray) -> np.ndarray:
    """plastic (0) where x < 0, fabric (2) where x > 0, IGNORE below z < -0.02."""
    labels = np.where(centres[:, 0] > 0, 2, 0)
    labels[centres[:, 2] < -0.02] = IGNORE
    return labels


def _pose(angle: float = 0.7, trans=(0.05, -0.02, 0.1)) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rotation_matrix(np.array([0.3, -0.5, 0.8]), angle)
    pose[:3, 3] = trans
    return pose


def _press(
    world_T_object: np.ndarray, point_o: np.ndarray, press_m: float, roll: float = 0.0
) -> np.ndarray:
    """Sensor pose pressing `press_m` into the sphere at object-frame surface point `point_o`."""
    normal_o = point_o / np.linalg.norm(point_o)
    p_w = transform_points(world_T_object, (normal_o * RADIUS)[None])[0]
    return pose_pressing(p_w, world_T_object[:3, :3] @ normal_o, press_m, roll)


@pytest.fixture(scope="module")
def two_material() -> DigitRenderer:
    renderer = DigitRenderer(_sphere(_half_sphere_labels), noise_std=0.0)
    yield renderer
    renderer.close()


def test_depth_round_trip_points_lie_on_mesh(two_material: DigitRenderer) -> None:
    world_T_object = _pose()
    world_T_sensor = _press(world_T_object, np.array([0.2, 0.5, 0.8]), 1.5e-3, roll=0.4)
    out = two_material.render(world_T_object, world_T_sensor)
    assert out.contact_mask.sum() > 1000
    points_s = backproject(out.depth, two_material.intrinsics)
    assert len(points_s) == out.contact_mask.sum()  # depth is > 0 exactly on contact
    assert points_s[:, 2].max() < GEL_DISTANCE_M  # in front of the gel plane, +z forward
    points_o = transform_points(invert_pose(world_T_object) @ world_T_sensor, points_s)
    _, dist, _ = trimesh.proximity.closest_point(two_material.obj.mesh, points_o[::10])
    assert dist.max() < 0.5e-3
    # Tighter, against the analytic sphere (the icosphere's facets sag by about 6 um).
    assert np.abs(np.linalg.norm(points_o, axis=1) - RADIUS).max() < 15e-6


@pytest.mark.parametrize("press_mm", [0.5, 1.0])
def test_contact_patch_has_the_analytic_radius(
    two_material: DigitRenderer, press_mm: float
) -> None:
    d = press_mm * 1e-3
    world_T_sensor = _press(np.eye(4), np.array([0.0, 0.0, 1.0]), d)
    out = two_material.render(np.eye(4), world_T_sensor)
    expected_px = np.sqrt(2 * RADIUS * d - d * d) * DIGIT_INTRINSICS.fx / GEL_DISTANCE_M
    rows, cols = np.nonzero(out.contact_mask)
    radius_px = np.sqrt(out.contact_mask.sum() / np.pi)
    assert abs(radius_px - expected_px) < 2.0
    assert (
        abs(rows.mean() - DIGIT_INTRINSICS.cy) < 1.0
        and abs(cols.mean() - DIGIT_INTRINSICS.cx) < 1.0
    )
    # Deepest point at the centre: penetration equals the press.
    assert GEL_DISTANCE_M - out.depth[out.contact_mask].min() == pytest.approx(d, abs=2e-5)


def test_no_contact_when_one_millimetre_away(two_material: DigitRenderer) -> None:
    world_T_sensor = _press(np.eye(4), np.array([0.0, 0.0, 1.0]), -1e-3)
    out = two_material.render(np.eye(4), world_T_sensor)
    assert not out.in_contact
    assert not out.depth.any()
    assert (out.material == IGNORE).all()
    np.testing.assert_array_equal(out.image, two_material.background_image)  # noise_std=0


def test_output_types_and_shapes(two_material: DigitRenderer) -> None:
    out = two_material.render(np.eye(4), _press(np.eye(4), np.array([0.0, 0.0, 1.0]), 1e-3))
    assert out.image.shape == (320, 240, 3) and out.image.dtype == np.uint8
    assert out.depth.shape == (320, 240) and out.depth.dtype == np.float32
    assert out.contact_mask.dtype == bool and out.material.dtype == np.int16
    assert two_material.background_image.shape == (320, 240, 3)
    assert two_material.intrinsics == DIGIT_INTRINSICS


def test_material_map_matches_the_faces_under_each_pixel(two_material: DigitRenderer) -> None:
    world_T_object = _pose(angle=-0.4)
    # Touch where the plastic/fabric border (x = 0) crosses the top of the sphere.
    world_T_sensor = _press(world_T_object, np.array([0.0, 0.3, 1.0]), 1.5e-3, roll=0.9)
    out = two_material.render(world_T_object, world_T_sensor)
    points_o = transform_points(
        invert_pose(world_T_object) @ world_T_sensor, backproject(out.depth, DIGIT_INTRINSICS)
    )
    labels = out.material[out.contact_mask]
    expected = np.where(points_o[:, 0] > 0, 2, 0)
    clear = np.abs(points_o[:, 0]) > 0.3e-3  # away from the border's triangle staircase
    assert (labels[clear] == expected[clear]).mean() > 0.995
    assert {0, 2} <= set(np.unique(labels).tolist())


def test_ignore_faces_are_in_contact_without_material(two_material: DigitRenderer) -> None:
    world_T_sensor = _press(np.eye(4), np.array([0.0, 0.0, -1.0]), 1e-3)  # bottom: IGNORE faces
    out = two_material.render(np.eye(4), world_T_sensor)
    assert out.in_contact
    assert (out.material == IGNORE).all()


def test_ignore_faces_press_as_the_nearest_labelled_material() -> None:
    """Scoring ignores the sphere's cap; the gel feels it as the fabric round it."""
    world_T_sensor = _press(np.eye(4), np.array([0.0, 0.0, -1.0]), 1e-3)  # inside the cap
    outs = {}
    for name, labels_fn in (
        ("capped", lambda c: np.where(c[:, 2] < -0.02, IGNORE, 2)),
        ("fabric", lambda c: np.full(len(c), 2)),
        ("plastic", lambda c: np.full(len(c), 0)),
    ):
        renderer = DigitRenderer(_sphere(labels_fn), noise_std=0.0)
        outs[name] = renderer.render(np.eye(4), world_T_sensor)
        renderer.close()
    assert (outs["capped"].material == IGNORE).all()  # the ground truth keeps it ignored
    np.testing.assert_array_equal(outs["capped"].image, outs["fabric"].image)
    assert np.abs(outs["capped"].image.astype(int) - outs["plastic"].image).max() > 10
    capped = _sphere(lambda c: np.where(c[:, 2] < -0.02, IGNORE, 2))
    generic = DigitRenderer(capped, noise_std=0.0, ignored_faces="generic")
    image = generic.render(np.eye(4), world_T_sensor).image
    generic.close()
    assert np.abs(image.astype(int) - outs["fabric"].image).max() > 10
    with pytest.raises(ValueError, match="ignored_faces"):
        DigitRenderer(capped, ignored_faces="felt")


def test_penetration_beyond_the_gel_range_is_still_reported_as_contact(
    two_material: DigitRenderer,
) -> None:
    out = two_material.render(
        np.eye(4), _press(np.eye(4), np.array([0.0, 0.0, 1.0]), 2 * MAX_PENETRATION_M)
    )
    assert out.in_contact and np.isfinite(out.image).all()


@pytest.fixture(scope="module")
def single_material_renders() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """name -> (image, background, contact mask) for each material pressed 1 mm, no noise."""
    out = {}
    world_T_sensor = _press(np.eye(4), np.array([0.0, 0.0, 1.0]), 1e-3)
    for i, name in enumerate(MATERIALS):
        renderer = DigitRenderer(_sphere(lambda c, i=i: np.full(len(c), i)), noise_std=0.0)
        render = renderer.render(np.eye(4), world_T_sensor)
        out[name] = (
            render.image.astype(float),
            renderer.background_image.astype(float),
            render.contact_mask,
        )
        renderer.close()
    return out


def test_contact_is_clearly_visible_against_the_background(single_material_renders) -> None:
    for name, (image, background, mask) in single_material_renders.items():
        diff = np.abs(image - background).mean(axis=2)
        assert diff[mask].mean() > 8.0, name
        assert diff[:20, :].max() == 0.0, name  # far from the patch: untouched background


def test_fabric_imprint_is_larger_and_softer_than_metal(single_material_renders) -> None:
    def visible_area_and_edge(name: str) -> tuple[int, float]:
        image, background, _ = single_material_renders[name]
        diff = np.abs(image - background).mean(axis=2)
        visible = diff > 3.0
        rows = visible.any(axis=1)
        return int(visible.sum()), float(rows.sum())

    fabric_area, fabric_rows = visible_area_and_edge("fabric")
    metal_area, metal_rows = visible_area_and_edge("metal")
    assert (
        single_material_renders["fabric"][2].sum() == single_material_renders["metal"][2].sum()
    )  # same geometry
    assert fabric_area > 1.15 * metal_area
    assert fabric_rows > metal_rows


def test_noise_has_the_requested_std() -> None:
    renderer = DigitRenderer(_sphere(subdivisions=2), noise_std=3.0, seed=4)
    out = renderer.render(np.eye(4), _press(np.eye(4), np.array([0.0, 0.0, 1.0]), -2e-3))
    diff = out.image.astype(float) - renderer.background_image.astype(float)
    assert diff.std() == pytest.approx(3.0, rel=0.1)
    again = DigitRenderer(_sphere(subdivisions=2), noise_std=3.0, seed=4)
    np.testing.assert_array_equal(
        again.render(np.eye(4), _press(np.eye(4), np.array([0.0, 0.0, 1.0]), -2e-3)).image,
        out.image,
    )
    renderer.close()
    again.close()


def test_bad_pose_shapes_raise() -> None:
    renderer = DigitRenderer(_sphere(subdivisions=1))
    with pytest.raises(ValueError):
        renderer.render(np.eye(3), np.eye(4))
    with pytest.raises(ValueError):
        DigitRenderer(_sphere(subdivisions=1), noise_std=-1.0)


# ------------------------------------------------------------------ backgrounds
def test_procedural_background_is_digit_like_and_deterministic() -> None:
    bg = procedural_background(seed=3)
    assert bg.shape == (320, 240, 3) and bg.dtype == np.uint8
    np.testing.assert_array_equal(bg, procedural_background(seed=3))
    assert np.abs(bg.astype(int) - procedural_background(seed=4)).mean() > 1.0
    f = bg.astype(float)
    left, right = f[:, :80], f[:, -80:]
    assert left[..., 0].mean() > right[..., 0].mean() + 20  # red LED on the left
    assert right[..., 1].mean() > left[..., 1].mean() + 10  # green LED on the right
    assert f[-60:, :, 2].mean() > f[:60, :, 2].mean()  # blue LED at the bottom
    assert f[150:170, 100:140].mean() > f[:10, :10].mean()  # vignetting


def test_background_from_array_path_and_errors(tmp_path) -> None:
    bg = procedural_background(seed=1)
    np.testing.assert_array_equal(resolve_background(bg), bg)
    with pytest.raises(ValueError):
        resolve_background(bg[:100])
    import cv2

    big = cv2.resize(bg, (480, 640))
    cv2.imwrite(str(tmp_path / "big.png"), cv2.cvtColor(big, cv2.COLOR_RGB2BGR))
    loaded = load_background(tmp_path / "big.png")
    assert loaded.shape == (320, 240, 3)
    assert np.abs(loaded.astype(int) - bg).mean() < 3.0  # RGB order kept through the BGR file
    with pytest.raises(DataError, match="does not exist"):
        load_background(tmp_path / "missing.png")
    (tmp_path / "broken.png").write_bytes(b"not an image")
    with pytest.raises(DataError, match="not a readable image"):
        load_background(tmp_path / "broken.png")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="no PNG/JPG"):
        resolve_background(empty)
    with pytest.raises(DataError):
        _ = DigitRenderer(
            _sphere(subdivisions=1), background=str(tmp_path / "missing.png")
        ).background_image


def test_real_backgrounds_load(shared_data) -> None:
    folder = shared_data / "digit_real" / "backgrounds"
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg"))
    assert len(files) > 10
    for path in files:
        bg = load_background(path)
        assert bg.shape == (320, 240, 3) and bg.dtype == np.uint8
        assert 40 < bg.mean() < 200
    # A folder picks its seed-th frame, so each finger can get its own real background.
    np.testing.assert_array_equal(resolve_background(folder, seed=1), load_background(files[1]))
    renderer = DigitRenderer(_sphere(subdivisions=2), background=str(files[0]), noise_std=0.0)
    out = renderer.render(np.eye(4), _press(np.eye(4), np.array([0.0, 0.0, 1.0]), 1e-3))
    np.testing.assert_array_equal(out.image[:20], load_background(files[0])[:20])
    renderer.close()


def test_contact_sheet_writes_a_png(tmp_path) -> None:
    import cv2

    path = contact_sheet(tmp_path / "sheet.png")
    image = cv2.imread(str(path))
    # background, four materials at the pole, wood on the side: 244-pixel panels
    assert image is not None and image.shape[0] >= 320 and image.shape[1] == 6 * 244
    plain = cv2.imread(str(contact_sheet(tmp_path / "plain.png", side_views=())))
    assert plain.shape[1] == 5 * 244


def test_depth_smoothing_hides_mesh_facets_but_not_ground_truth() -> None:
    """A coarse sphere (1.9 mm facets, like the shipped objects) renders closer to a fine one with smoothing than without."""
    import cv2

    pose = _press(np.eye(4), np.array([0.1, 0.2, 1.0]), 1.2e-3)

    def render(subdivisions: int, smooth: float):
        renderer = DigitRenderer(
            _sphere(subdivisions=subdivisions), noise_std=0.0, texture_scale=0.0, smooth_px=smooth
        )
        out = renderer.render(np.eye(4), pose)
        renderer.close()
        return out

    reference = render(6, 0.0).image.astype(float)  # facets far below a pixel's slope change
    raw, smoothed = render(4, 0.0), render(4, 5.0)
    np.testing.assert_array_equal(raw.depth, smoothed.depth)  # ground truth is never smoothed
    interior = cv2.erode(raw.contact_mask.astype(np.uint8), np.ones((21, 21))) > 0
    error_raw = np.abs(raw.image - reference)[interior].mean()
    error_smoothed = np.abs(smoothed.image - reference)[interior].mean()
    assert error_smoothed < 0.6 * error_raw, (error_smoothed, error_raw)


def test_culling_skips_far_objects_and_never_drops_a_contact(two_material: DigitRenderer) -> None:
    rng = np.random.default_rng(7)
    world_T_object = _pose()
    culled = 0
    for _ in range(12):
        point = rng.normal(size=3)
        press = rng.uniform(-6e-3, 1.5e-3)
        world_T_sensor = _press(
            world_T_object, point / np.linalg.norm(point), press, roll=rng.uniform(0, 6)
        )
        sensor_T_object = invert_pose(world_T_sensor) @ world_T_object
        visible = two_material._may_be_visible(sensor_T_object)
        culled += not visible
        if not visible:
            two_material._may_be_visible = lambda _pose: True  # force the GL pass
            try:
                forced = two_material.render(world_T_object, world_T_sensor)
            finally:
                del two_material._may_be_visible
            assert not forced.depth.any()
        if press > 0:
            assert visible
    assert culled > 0


@pytest.mark.parametrize("gel_point", [(0.0085, 0.002), (-0.003, -0.0115)])
def test_edge_press_puts_the_gel_point_deepest_and_lifts_the_centre(gel_point) -> None:
    point, normal = np.array([0.01, -0.02, 0.05]), np.array([0.0, 0.6, 0.8])
    tilt, press = np.deg2rad(25.0), 1.2e-3
    pose = pose_pressing_edge(point, normal, press, gel_point, tilt, roll_rad=0.3)
    rotation = pose[:3, :3]
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) > 0.0
    # The chosen gel point sits `press` below the surface point, along the normal.
    gel = transform_points(pose, np.array([[*gel_point, GEL_DISTANCE_M]]))[0]
    np.testing.assert_allclose(gel, point - normal * press, atol=1e-12)
    # The sensor axis is tilted by exactly `tilt` from the inward normal ...
    assert np.isclose(np.arccos(np.clip(rotation[:, 2] @ -normal, -1, 1)), tilt)
    # ... toward the side that lifts the gel centre: it stands off the surface.
    centre = transform_points(pose, np.array([[0.0, 0.0, GEL_DISTANCE_M]]))[0]
    lift = np.linalg.norm(gel_point) * np.sin(tilt) - press
    assert np.isclose(normal @ (centre - point), lift, atol=1e-12) and lift > 0
    with pytest.raises(ValueError, match="gel_point"):
        pose_pressing_edge(point, normal, press, (0.0, 0.0), tilt)


def test_edge_press_renders_a_strip_along_the_sensor_border(two_material: DigitRenderer) -> None:
    world_T_object = np.eye(4)
    top = np.array([0.0, 0.0, RADIUS])
    pose = pose_pressing_edge(top, np.array([0.0, 0.0, 1.0]), 1.5e-3, (0.0085, 0.0), 0.5)
    out = two_material.render(world_T_object, pose)
    columns = np.nonzero(out.contact_mask.any(axis=0))[0]
    assert out.contact_mask.sum() > 300
    assert columns.min() > out.contact_mask.shape[1] // 2  # only the +x (right) side touches
    assert edge_share(out.contact_mask, 16) > 0.35
