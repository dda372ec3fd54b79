"""CameraRenderer: depth round trip, mask under occlusion, colours, noise, front-left pose."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.frame import CameraReading
from neuralfeels_sem.core.geometry import (
    backproject,
    invert_pose,
    project,
    rotation_matrix,
    transform_points,
)
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.sim.camera_renderer import (
    CameraRenderer,
    front_left_camera_pose,
    material_colour,
)

MATERIALS = tuple(DEFAULT_MATERIALS)


def _object() -> MaterialObject:
    """A 6 x 4 x 3 cm box: plastic where x < 0, fabric where x > 0, IGNORE on the bottom."""
    mesh = trimesh.creation.box(extents=(0.06, 0.04, 0.03)).subdivide().subdivide()
    centres = mesh.triangles_center
    labels = np.where(centres[:, 0] > 0, 2, 0)
    labels[centres[:, 2] < -0.0149] = IGNORE
    return MaterialObject("box", mesh, labels, MATERIALS)


def _pose() -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rotation_matrix(np.array([0.0, 0.0, 1.0]), 0.4)
    pose[:3, 3] = (0.01, -0.01, 0.12)
    return pose


TARGET = np.array([0.01, -0.01, 0.12])


@pytest.fixture(scope="module")
def camera() -> CameraRenderer:
    renderer = CameraRenderer(
        _object(), world_T_camera=front_left_camera_pose(TARGET, distance=0.25)
    )
    yield renderer
    renderer.close()


def test_depth_round_trip_points_lie_on_mesh(camera: CameraRenderer) -> None:
    reading = camera.render(_pose())
    assert isinstance(reading, CameraReading)
    assert reading.rgb.shape == (240, 320, 3) and reading.rgb.dtype == np.uint8
    assert reading.depth.dtype == np.float32 and reading.mask.dtype == bool
    assert reading.mask.sum() > 2000
    points_c = backproject(reading.depth, reading.intrinsics, reading.mask)
    assert (points_c[:, 2] > 0).all()
    object_T_camera = invert_pose(_pose()) @ reading.world_T_camera
    points_o = transform_points(object_T_camera, points_c)
    _, dist, _ = trimesh.proximity.closest_point(camera.obj.mesh, points_o[::7])
    assert dist.max() < 2e-3
    assert np.median(dist) < 0.2e-3


def test_object_centre_projects_to_the_mask_centre(camera: CameraRenderer) -> None:
    reading = camera.render(_pose())
    centre_c = transform_points(invert_pose(reading.world_T_camera), TARGET[None])
    u, v = project(centre_c, reading.intrinsics)[0]
    rows, cols = np.nonzero(reading.mask)
    assert abs(cols.mean() - u) < 8 and abs(rows.mean() - v) < 8
    # The front-left pose looks straight at its target.
    assert abs(u - reading.intrinsics.cx) < 0.5 and abs(v - reading.intrinsics.cy) < 0.5


def test_front_left_pose_is_above_in_front_and_left() -> None:
    pose = front_left_camera_pose(np.zeros(3), distance=0.4, azimuth_deg=45.0, elevation_deg=35.0)
    eye = pose[:3, 3]
    assert np.linalg.norm(eye) == pytest.approx(0.4)
    assert eye[0] > 0 and eye[1] > 0 and eye[2] == pytest.approx(0.4 * np.sin(np.deg2rad(35.0)))
    assert pose[:3, 2] @ (-eye / np.linalg.norm(eye)) == pytest.approx(
        1.0
    )  # +z looks at the target
    assert pose[2, 1] < 0  # image rows (+y) point down in the world
    with pytest.raises(ValueError):
        front_left_camera_pose(np.zeros(3), distance=0.0)


def test_occluder_hides_the_object_in_mask_and_depth(camera: CameraRenderer) -> None:
    clear = camera.render(_pose())
    # A finger-sized box halfway between the camera and the object.
    eye = clear.world_T_camera[:3, 3]
    finger = trimesh.creation.box(extents=(0.02, 0.02, 0.02))
    finger_pose = np.eye(4)
    finger_pose[:3, 3] = 0.5 * (eye + TARGET)
    hidden = camera.render(_pose(), occluders=[(finger, finger_pose)])
    assert hidden.mask.sum() < clear.mask.sum() - 200
    assert not (hidden.mask & ~clear.mask).any()
    lost = clear.mask & ~hidden.mask
    assert (hidden.depth[lost] < clear.depth[lost] - 0.05).all()  # the occluder is in front
    # Occluders not passed on a later frame disappear again.
    np.testing.assert_array_equal(camera.render(_pose()).mask, clear.mask)


def test_colours_follow_the_material_palette(camera: CameraRenderer) -> None:
    reading = camera.render(_pose())
    points_o = transform_points(
        invert_pose(_pose()) @ reading.world_T_camera,
        backproject(reading.depth, reading.intrinsics, reading.mask),
    )
    rgb = reading.rgb[reading.mask].astype(float)
    fabric, plastic = rgb[points_o[:, 0] > 0.002], rgb[points_o[:, 0] < -0.002]
    assert len(fabric) > 300 and len(plastic) > 300
    assert fabric[:, 0].mean() > fabric[:, 2].mean() + 20  # fabric is red
    assert plastic[:, 2].mean() > plastic[:, 0].mean() + 20  # plastic is blue
    assert material_colour("unobtainium") == material_colour("unobtainium")


def test_table_is_seen_but_not_masked() -> None:
    renderer = CameraRenderer(
        _object(), world_T_camera=front_left_camera_pose(TARGET, distance=0.25), table_height=0.105
    )
    reading = renderer.render(_pose())
    assert (reading.depth > 0).mean() > 0.9  # the table fills the background
    assert 2000 < reading.mask.sum() < (reading.depth > 0).sum() - 5000
    renderer.close()


def test_realsense_noise_drops_edges_and_keeps_the_mask() -> None:
    pose = front_left_camera_pose(TARGET, distance=0.25)
    clean = CameraRenderer(_object(), world_T_camera=pose)
    noisy = CameraRenderer(_object(), world_T_camera=pose, depth_noise="realsense", seed=3)
    a, b = clean.render(_pose()), noisy.render(_pose())
    np.testing.assert_array_equal(a.mask, b.mask)  # the mask is what is seen, noise or not
    assert not ((b.depth > 0) & (a.depth == 0)).any()  # noise never invents a surface
    kept = (a.depth > 0) & (b.depth > 0)
    assert 0 < (b.depth[kept] - a.depth[kept]).std() < 0.002
    assert (b.depth > 0).sum() < (a.depth > 0).sum()  # the outline lost its pixels
    clean.close()
    noisy.close()


def test_scenery_is_seen_but_not_masked() -> None:
    from neuralfeels_sem.sim.lab_scenery import backdrop

    pose = front_left_camera_pose(TARGET, distance=0.25)
    plain = CameraRenderer(_object(), world_T_camera=pose)
    walled = CameraRenderer(_object(), world_T_camera=pose, scenery=[backdrop(pose, 0.6)])
    a, b = plain.render(_pose()), walled.render(_pose())
    np.testing.assert_array_equal(a.mask, b.mask)
    assert (b.depth > 0).mean() > 0.9 > (a.depth > 0).mean()
    plain.close()
    walled.close()


def test_bad_arguments_raise() -> None:
    with pytest.raises(ValueError):
        CameraRenderer(_object(), fov_y_deg=0.0)
    with pytest.raises(ValueError, match="depth_noise"):
        CameraRenderer(_object(), depth_noise="kinect")
    renderer = CameraRenderer(_object())
    with pytest.raises(ValueError):
        renderer.render(np.eye(3))
    with pytest.raises(ValueError):
        renderer.set_camera_pose(np.eye(3))


def test_occluder_cache_stays_bounded_when_callers_rebuild_meshes(
    camera: CameraRenderer, monkeypatch
) -> None:
    from neuralfeels_sem.sim import camera_renderer

    monkeypatch.setattr(camera_renderer, "_MAX_CACHED_OCCLUDERS", 6)
    far = np.eye(4)
    far[:3, 3] = (2.0, 2.0, 2.0)
    for _ in range(15):
        camera.render(_pose(), occluders=[(trimesh.creation.box(extents=(0.01, 0.01, 0.01)), far)])
    assert len(camera._occluder_nodes) <= 7
