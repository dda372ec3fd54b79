"""closest_faces and closest_surface_points agree with a brute-force search over every face."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.eval.matching import sample_faces_uniform
from neuralfeels_sem.objects.proximity import closest_faces, closest_surface_points


def _brute_force(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    tri = np.asarray(mesh.triangles)
    return np.array(
        [
            np.linalg.norm(
                trimesh.triangles.closest_point(tri, np.repeat(p[None], len(tri), 0)) - p, axis=1
            ).min()
            for p in points
        ]
    )


def test_matches_brute_force_near_and_far() -> None:
    rng = np.random.default_rng(0)
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    mesh.vertices *= 1.0 + 0.2 * rng.uniform(size=(len(mesh.vertices), 1))  # bumpy, uneven faces
    near, _ = trimesh.sample.sample_surface(mesh, 150, seed=1)
    near = near + rng.normal(scale=0.002, size=near.shape)
    far = rng.uniform(-0.1, 0.1, size=(30, 3))  # exercises the growing-k rounds
    points = np.vstack([near, far])
    faces, distance = closest_faces(mesh, points, k=4)
    expected = _brute_force(mesh, points)
    np.testing.assert_allclose(distance, expected, atol=1e-12)
    # The returned face really is at that distance.
    on_face = trimesh.triangles.closest_point(mesh.triangles[faces], points)
    np.testing.assert_allclose(np.linalg.norm(on_face - points, axis=1), distance, atol=1e-12)


def test_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        closest_faces(trimesh.creation.icosphere(), np.zeros((4, 2)))


def test_surface_points_find_their_own_face_and_themselves() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    faces = np.arange(len(mesh.faces))
    points, true_faces = sample_faces_uniform(mesh.vertices, mesh.faces, faces, 3000, seed=0)
    found, distance, closest = closest_surface_points(mesh, points, k=8)
    assert distance.max() < 1e-7  # float rounding in the point-triangle projection
    np.testing.assert_allclose(closest, points, atol=1e-7)
    # Points on a shared edge may name either face; all others name their own.
    assert np.mean(found == true_faces) > 0.999


def test_closest_points_off_long_thin_faces_are_exact() -> None:
    # A box has long thin faces: the nearest centroids alone can miss the closest face.
    mesh = trimesh.creation.box(extents=(0.1, 0.01, 0.01))
    points = np.random.default_rng(0).uniform(-0.06, 0.06, size=(500, 3))
    faces, distance, closest = closest_surface_points(mesh, points, k=2)
    np.testing.assert_allclose(distance, _brute_force(mesh, points), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(closest - points, axis=1), distance, atol=1e-12)
    on_face = trimesh.triangles.closest_point(mesh.triangles[faces], points)
    np.testing.assert_allclose(on_face, closest, atol=1e-12)


def test_points_beyond_reach_and_an_empty_query() -> None:
    mesh = trimesh.creation.box(extents=(0.02, 0.02, 0.02))
    faces, distance, closest = closest_surface_points(mesh, np.array([[0.011, 0, 0], [1, 0, 0]]),
                                                      within=0.01)  # fmt: skip
    assert faces[0] >= 0 and distance[0] == pytest.approx(0.001)
    assert faces[1] == -1 and distance[1] == np.inf and np.isnan(closest[1]).all()
    faces, distance, closest = closest_surface_points(mesh, np.zeros((0, 3)))
    assert faces.shape == (0,) and distance.shape == (0,) and closest.shape == (0, 3)
