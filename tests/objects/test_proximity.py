"""closest_faces agrees with a brute-force search over every face."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.objects.proximity import closest_faces


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
