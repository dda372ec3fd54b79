"""RealSenseDepthNoise: std grows with z^2, discontinuities and grazing surfaces lose depth."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.sim.depth_noise import RealSenseDepthNoise, RealSenseNoiseConfig

INTRINSICS = Intrinsics.from_fov(160, 120, 50.0)


def _noise(**overrides) -> RealSenseDepthNoise:
    return RealSenseDepthNoise(RealSenseNoiseConfig(**overrides), INTRINSICS, seed=0)


@pytest.mark.parametrize("z", [0.3, 0.6, 1.2])
def test_std_follows_the_stereo_formula(z: float) -> None:
    noise = _noise(dropout=0.0)
    flat = np.full((INTRINSICS.height, INTRINSICS.width), z, np.float32)
    noisy = noise(flat)
    kept = noisy > 0
    expected = z * z * 0.08 / (447.0 * 0.05)
    assert kept.mean() > 0.99  # a flat wall facing the camera loses no pixels
    assert (noisy[kept] - z).std() == pytest.approx(expected, rel=0.1)


def test_std_quadruples_when_distance_doubles() -> None:
    noise = _noise()
    assert noise.sigma(np.float32(0.8)) / noise.sigma(np.float32(0.4)) == pytest.approx(4.0)


def test_depth_edges_are_dropped_and_flat_parts_kept() -> None:
    depth = np.full((INTRINSICS.height, INTRINSICS.width), 0.8, np.float32)
    depth[40:80, 60:100] = 0.3  # a box in front of a wall
    noisy = _noise(dropout=0.0)(depth)
    assert (noisy[40:80, 59] == 0).all() and (noisy[40:80, 60] == 0).all()  # both sides
    assert (noisy[50:70, 70:90] > 0).all()  # the box's inside
    assert (noisy[5:30, 5:150] > 0).all()  # the wall away from the box
    assert (noisy[depth == 0] == 0).all()


def test_grazing_surfaces_are_dropped() -> None:
    # Depth growing by a constant factor per row is a plane at a constant angle to the rays:
    # a row spacing of z / fy and a depth step of (ratio - 1) z make tan(angle) = (ratio - 1) fy.
    rows = np.arange(40, dtype=np.float32)[:, None]
    noise = _noise(dropout=0.0, edge_jump_m=10.0)

    def plane(tan_angle: float) -> np.ndarray:
        depth = np.zeros((INTRINSICS.height, INTRINSICS.width), np.float32)
        depth[:40] = 0.3 * (1.0 + tan_angle / INTRINSICS.fy) ** rows
        return depth

    assert (noise(plane(np.tan(np.deg2rad(85.0))))[1:39] == 0).mean() > 0.9
    assert (noise(plane(np.tan(np.deg2rad(60.0))))[1:39] == 0).mean() < 0.01


def test_dropout_share() -> None:
    flat = np.full((INTRINSICS.height, INTRINSICS.width), 0.5, np.float32)
    assert (_noise(dropout=0.1)(flat) == 0).mean() == pytest.approx(0.1, abs=0.02)


@pytest.mark.parametrize(
    "key, value",
    [("baseline_m", 0.0), ("edge_width_px", -1), ("grazing_deg", 0.0), ("dropout", 1.0)],
)
def test_bad_settings_name_the_key(key: str, value: float) -> None:
    with pytest.raises(ValueError, match=key):
        RealSenseNoiseConfig(**{key: value})
