"""Signed-distance primitives give exact distances; the mesher closes the surface."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.objects import sdf as S


def test_primitives_exact_distances() -> None:
    p = np.array([[0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.3, 0.0]])
    np.testing.assert_allclose(S.sphere((0, 0, 0), 0.05)(p), [0.05, -0.05, 0.25])
    # Capsule along x from 0 to 0.1, radius 0.01: beyond the end cap, beside the segment.
    cap = S.capsule((0, 0, 0), (0.1, 0, 0), 0.01)
    np.testing.assert_allclose(cap(np.array([[0.13, 0.0, 0.0], [0.05, 0.04, 0.0]])), [0.02, 0.03])
    cyl = S.rounded_cylinder(0.0, 0.1, 0.03, 0.005)
    q = np.array([[0.05, 0.0, 0.05], [0.0, 0.0, 0.12], [0.0, 0.0, 0.05]])
    np.testing.assert_allclose(cyl(q), [0.02, 0.02, -0.03], atol=1e-12)
    tor = S.torus(0.0, 0.02, 0.005)
    np.testing.assert_allclose(tor(np.array([[0.02, 0.0, 0.0], [0.0, 0.0, 0.0]])), [-0.005, 0.015])
    box = S.rounded_box((0, 0, 0), (0.02, 0.01, 0.01), 0.002)
    np.testing.assert_allclose(box(np.array([[0.03, 0.0, 0.0], [0.0, 0.0, 0.0]])), [0.01, -0.01])


def test_ellipsoid_is_exact_on_axes_and_zero_on_surface() -> None:
    f = S.ellipsoid((0, 0, 0), (0.03, 0.02, 0.01))
    np.testing.assert_allclose(
        f(np.array([[0.03, 0, 0], [0, 0.02, 0], [0, 0, 0.01]])), 0.0, atol=1e-12
    )
    np.testing.assert_allclose(f(np.array([[0.04, 0, 0], [0, 0, 0.03]])), [0.01, 0.02])
    np.testing.assert_allclose(f(np.array([[0.0, 0.0, 0.0]])), [-0.01])


def test_smooth_union_blends_below_min_and_matches_far_away() -> None:
    a, b = S.sphere((-0.02, 0, 0), 0.015), S.sphere((0.02, 0, 0), 0.015)
    u = S.smooth_union([a, b], k=0.01)
    p = np.array([[0.0, 0.0, 0.0], [-0.05, 0.0, 0.0]])
    plain = np.minimum(a(p), b(p))
    assert u(p)[0] < plain[0]  # the neck between the spheres is filled in
    np.testing.assert_allclose(u(p)[1], plain[1])  # far from the blend: exact


def test_mesh_sdf_sphere_is_closed_and_accurate() -> None:
    r, h = 0.03, 0.0015
    mesh = S.mesh_sdf(
        S.sphere((0.001, 0, 0), r),
        np.array([-0.031, -0.031, -0.031]),
        np.array([0.032, 0.031, 0.031]),
        h,
    )
    assert mesh.is_watertight and mesh.is_volume
    np.testing.assert_allclose(mesh.volume, 4 / 3 * np.pi * r**3, rtol=0.01)
    radii = np.linalg.norm(mesh.vertices - [0.001, 0, 0], axis=1)
    assert np.abs(radii - r).max() < 0.1 * h
    # Outward normals: face normals point away from the centre.
    centres = mesh.triangles_center - [0.001, 0, 0]
    assert (np.einsum("ij,ij->i", mesh.face_normals, centres) > 0).all()


def test_mesh_sdf_refuses_a_box_that_cuts_the_solid() -> None:
    with pytest.raises(ValueError, match="touches the box"):
        S.mesh_sdf(S.sphere((0, 0, 0), 0.05), np.array([-0.02] * 3), np.array([0.02] * 3), 0.002)
    with pytest.raises(ValueError, match="empty"):
        S.mesh_sdf(S.sphere((1, 1, 1), 0.01), np.array([-0.02] * 3), np.array([0.02] * 3), 0.002)


def test_target_faces_sets_the_resolution() -> None:
    f = S.sphere((0, 0, 0), 0.03)
    lo, hi = np.array([-0.035] * 3), np.array([0.035] * 3)
    for target in (12_000, 24_000):
        assert 0.8 * target < len(S.mesh_sdf_with_faces(f, lo, hi, target).faces) < 1.2 * target
    # Never coarser than 2 mm, whatever the target.
    assert len(S.mesh_sdf_with_faces(f, lo, hi, 100).faces) == len(
        S.mesh_sdf(f, lo, hi, 0.002).faces
    )


def test_displaced_offsets_near_the_surface_only() -> None:
    base = S.sphere((0, 0, 0), 0.03)
    f = S.displaced(base, lambda p: np.full(len(p), 0.001), max_offset=0.001)
    p = np.array([[0.031, 0.0, 0.0], [0.0, 0.0, 0.0], [0.02, 0.0, 0.0]])
    # Near the surface: moved out by 1 mm; far inside: untouched (sign is all that matters there).
    np.testing.assert_allclose(f(p), [0.0, -0.03, -0.01], atol=1e-15)
