"""Nearest-face lookup agrees with trimesh's exact query."""

from __future__ import annotations

import numpy as np
import trimesh

from neuralfeels_sem.eval.matching import sample_faces_uniform
from neuralfeels_sem.eval.surface import closest_faces


def test_surface_points_find_their_own_face() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    faces = np.arange(len(mesh.faces))
    points, true_faces = sample_faces_uniform(mesh.vertices, mesh.faces, faces, 3000, seed=0)
    found, distance, closest = closest_faces(mesh, points)
    assert distance.max() < 1e-7  # float rounding in the point-triangle projection
    np.testing.assert_allclose(closest, points, atol=1e-7)
    # Points on a shared edge may name either face; all others name their own.
    assert np.mean(found == true_faces) > 0.999


def test_off_surface_points_match_trimesh() -> None:
    # A box has long thin faces: the candidate search alone can miss, the fallback must not.
    mesh = trimesh.creation.box(extents=(0.1, 0.01, 0.01))
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.06, 0.06, size=(500, 3))
    face, distance, closest = closest_faces(mesh, points, candidates=2)
    exact_point, exact_distance, _ = trimesh.proximity.closest_point(mesh, points)
    np.testing.assert_allclose(distance, exact_distance, atol=1e-9)
    np.testing.assert_allclose(closest, exact_point, atol=1e-9)
    assert face.shape == (500,)


def test_empty_query() -> None:
    mesh = trimesh.creation.box()
    face, distance, closest = closest_faces(mesh, np.zeros((0, 3)))
    assert face.shape == (0,) and distance.shape == (0,) and closest.shape == (0, 3)
