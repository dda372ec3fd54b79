"""The image form of the matching percentage and its renderer (pyrender, EGL)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.geometry import Intrinsics, backproject, transform_points
from neuralfeels_sem.core.materials import BACKGROUND
from neuralfeels_sem.eval.image_matching import ImageMatcher, render_label_maps
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.mesh_render import DepthRenderer, orbit_views
from neuralfeels_sem.objects.material_object import MaterialObject
from tests.eval.objects import predict_by_y, predict_swap_x_positive, two_material_sphere


@pytest.fixture(scope="module")
def sphere() -> MaterialObject:
    return two_material_sphere()


@pytest.fixture(scope="module")
def matcher(sphere: MaterialObject) -> ImageMatcher:
    return ImageMatcher(sphere, views=4, size=128)


def test_rendered_depth_backprojects_onto_the_mesh() -> None:
    mesh = trimesh.creation.box(extents=(0.04, 0.06, 0.03))
    intrinsics = Intrinsics.from_fov(160, 120, 40.0)
    poses = orbit_views(np.zeros(3), 0.05, views=3, elevation_deg=25.0)
    with DepthRenderer(mesh, intrinsics) as renderer:
        for object_T_camera in poses:
            depth = renderer.render(object_T_camera)
            assert depth.shape == (120, 160) and depth.dtype == np.float32
            assert 0.1 < (depth > 0).mean() < 0.9  # object in view, background around it
            points = transform_points(object_T_camera, backproject(depth, intrinsics))
            _, distance, _ = trimesh.proximity.closest_point(mesh, points[::7])
            assert distance.max() < 1e-3
            assert np.median(distance) < 2e-4
            # Every point faces the camera (no back faces, no points behind it).
            assert (depth[depth > 0] > 0.01).all()


def test_orbit_views_look_at_the_centre() -> None:
    centre = np.array([0.01, -0.02, 0.03])
    for pose in orbit_views(centre, 0.05, views=4, elevation_deg=30.0):
        to_centre = centre - pose[:3, 3]
        np.testing.assert_allclose(pose[:3, 2], to_centre / np.linalg.norm(to_centre), atol=1e-12)
        assert pose[2, 3] > centre[2]  # above the object at positive elevation


def test_label_maps_shapes_and_conventions(matcher: ImageMatcher) -> None:
    maps = matcher.maps(predict_by_y)
    assert maps["gt"].shape == maps["pred"].shape == maps["diff"].shape == (4, 128, 128)
    assert maps["diff"].dtype == bool
    gt, pred = maps["gt"], maps["pred"]
    assert set(np.unique(gt)) == {BACKGROUND, -1, 0, 2}  # caps visible from 30 degrees up
    np.testing.assert_array_equal(pred == BACKGROUND, gt == BACKGROUND)
    assert gt[:, 0, 0].tolist() == [BACKGROUND] * 4  # corners are background
    # The prediction is shown on ignored pixels too (it is just not scored there).
    assert set(np.unique(pred[gt == -1])) <= {0, 2}


def test_perfect_predictor_has_an_empty_difference_mask(matcher: ImageMatcher) -> None:
    maps = matcher.maps(predict_by_y)
    assert not maps["diff"].any()
    assert maps["matching_pct_image"] == 100.0


@pytest.mark.parametrize(
    "predict",
    [
        predict_swap_x_positive,
        # Wrong on longitude stripes (a third of the area), seen alike from every view.
        lambda x: np.where(np.cos(6 * np.arctan2(x[:, 1], x[:, 0])) > 0.5, 3, predict_by_y(x)),
        lambda x: np.zeros(len(x), int),
    ],
)
def test_image_form_agrees_with_the_3d_form(
    sphere: MaterialObject, matcher: ImageMatcher, predict
) -> None:
    image = matcher.maps(predict)["matching_pct_image"]
    surface = MatchingEvaluator(sphere, num_samples=20000).score(predict)
    # Pixels weight visible surface by its projected area, samples by true area: close for
    # errors spread around the object, not equal (a band seen only from above would differ).
    assert image == pytest.approx(surface, abs=5.0)


def test_difference_mask_marks_exactly_the_wrong_roi_pixels(matcher: ImageMatcher) -> None:
    maps = matcher.maps(predict_swap_x_positive)
    roi = maps["gt"] >= 0
    np.testing.assert_array_equal(maps["diff"], roi & (maps["pred"] != maps["gt"]))
    assert maps["matching_pct_image"] == pytest.approx(100.0 * (1 - maps["diff"].sum() / roi.sum()))
    assert 0.3 < maps["diff"].sum() / roi.sum() < 0.7


def test_ground_truth_is_rendered_once(matcher: ImageMatcher) -> None:
    calls = []

    def counting(points: np.ndarray) -> np.ndarray:
        calls.append(len(points))
        return predict_by_y(points)

    matcher.maps(counting)
    matcher.maps(counting)
    assert len(calls) == 2 and calls[0] == calls[1] == len(matcher.points)


def test_render_label_maps_one_off_call(sphere: MaterialObject) -> None:
    maps = render_label_maps(sphere, predict_by_y, views=2, size=64, seed=3)
    assert maps["gt"].shape == (2, 64, 64)
    assert maps["matching_pct_image"] == 100.0
    # Another seed turns the ring of views, so the pictures differ.
    other = render_label_maps(sphere, predict_by_y, views=2, size=64, seed=0)
    assert not np.array_equal(maps["gt"], other["gt"])


def test_closing_a_depth_renderer_leaves_other_renderers_working() -> None:
    # The sim's tactile and camera renderers share the process-wide EGL display with ours.
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    intrinsics = Intrinsics.from_fov(48, 48, 40.0)
    pose = orbit_views(np.zeros(3), 0.05, views=1)[0]
    other = DepthRenderer(mesh, intrinsics)
    before = other.render(pose)
    with DepthRenderer(mesh, intrinsics) as renderer:
        renderer.render(pose)
    np.testing.assert_array_equal(other.render(pose), before)
    other.close()


def test_hidden_region_of_interest_gives_nan_image_score(sphere: MaterialObject) -> None:
    labels = np.where(sphere.mesh.triangles_center[:, 2] < -0.045, 0, -1)  # bottom cap only
    bottom = MaterialObject("bottom_only", sphere.mesh, labels, sphere.class_names)
    maps = render_label_maps(bottom, predict_by_y, views=2, size=32, elevation_deg=60.0)
    assert np.isnan(maps["matching_pct_image"])
    assert not (maps["gt"] >= 0).any() and not maps["diff"].any()
    assert MatchingEvaluator(bottom, 500).score(lambda x: np.zeros(len(x), dtype=np.int64)) == 100.0
