"""Real SH basis: closed-form values at the axes, orthonormality, shapes, gradients."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from neuralfeels_sem.fields.spherical_harmonics import (
    SphericalHarmonicsEncoding,
    num_sh_coefficients,
    spherical_harmonics,
)

Y00 = 0.5 / math.sqrt(math.pi)
Y1 = math.sqrt(3 / (4 * math.pi))
Y20_POLE = math.sqrt(5 / (16 * math.pi)) * 2  # sqrt(5/(16 pi)) (3z^2 - 1) at z = 1
Y20_EQUATOR = -math.sqrt(5 / (16 * math.pi))
Y30_POLE = math.sqrt(7 / (16 * math.pi)) * 2  # sqrt(7/(16 pi)) (5z^3 - 3z) at z = 1
Y3_SECTORAL = math.sqrt(35 / (32 * math.pi))  # coefficient of x (x^2 - 3y^2) and y (3x^2 - y^2)
Y31 = math.sqrt(21 / (32 * math.pi))  # coefficient of x (5z^2 - 1) and y (5z^2 - 1)


def _expected(direction: str) -> list[float]:
    """Closed-form values of the 16 real SH at +x, +y, +z (nerfstudio order)."""
    e = [0.0] * 16
    e[0] = Y00
    if direction == "x":
        e[3] = Y1
        e[6] = Y20_EQUATOR
        e[8] = math.sqrt(15 / (16 * math.pi))  # sqrt(15/(16 pi)) (x^2 - y^2)
        e[13] = -Y31
        e[15] = Y3_SECTORAL
    elif direction == "y":
        e[1] = Y1
        e[6] = Y20_EQUATOR
        e[8] = -math.sqrt(15 / (16 * math.pi))
        e[9] = -Y3_SECTORAL
        e[11] = -Y31
    else:
        e[2] = Y1
        e[6] = Y20_POLE
        e[12] = Y30_POLE
    return e


@pytest.mark.parametrize(
    ("direction", "vector"), [("x", (1, 0, 0)), ("y", (0, 1, 0)), ("z", (0, 0, 1))]
)
def test_basis_at_axes_matches_closed_form(direction: str, vector: tuple[int, int, int]) -> None:
    got = spherical_harmonics(torch.tensor([vector], dtype=torch.float64), degree=3)[0]
    assert got.shape == (16,)
    torch.testing.assert_close(
        got, torch.tensor(_expected(direction), dtype=torch.float64), rtol=0, atol=1e-12
    )
    # The commonly quoted constants, as a guard against a transcription slip above.
    assert got[0].item() == pytest.approx(0.2820948, abs=1e-7)
    assert got.abs().max().item() == pytest.approx(
        {"x": 0.5900436, "y": 0.5900436, "z": 0.7463526}[direction], abs=1e-7
    )


def test_basis_is_orthonormal_on_the_sphere() -> None:
    # Gauss-Legendre in cos(theta) x uniform in phi integrates these polynomials exactly.
    nodes_np, weights_np = np.polynomial.legendre.leggauss(8)
    nodes, weights = torch.from_numpy(nodes_np), torch.from_numpy(weights_np)
    n_phi = 16
    phi = torch.arange(n_phi, dtype=torch.float64) * (2 * math.pi / n_phi)
    z = nodes[:, None].expand(-1, n_phi)
    r = torch.sqrt(1 - z**2)
    dirs = torch.stack([r * torch.cos(phi), r * torch.sin(phi), z], dim=-1).reshape(-1, 3)
    w = (weights[:, None] * (2 * math.pi / n_phi)).expand(-1, n_phi).reshape(-1)
    basis = spherical_harmonics(dirs, degree=3)  # (M, 16)
    gram = basis.T @ (basis * w[:, None])
    torch.testing.assert_close(gram, torch.eye(16, dtype=torch.float64), rtol=0, atol=1e-12)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_encoding_output_size_and_normalisation(degree: int) -> None:
    enc = SphericalHarmonicsEncoding(degree)
    assert enc.out_dim == num_sh_coefficients(degree) == (degree + 1) ** 2
    d = torch.randn(7, 3, dtype=torch.float64)
    # The encoding normalises: scaling a direction does not change it.
    torch.testing.assert_close(enc(d), enc(3.5 * d))
    torch.testing.assert_close(
        enc(d), spherical_harmonics(d / d.norm(dim=-1, keepdim=True), degree)
    )


def test_encoding_gradcheck() -> None:
    d = torch.randn(5, 3, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(SphericalHarmonicsEncoding(3), (d,))


def test_bad_inputs_raise() -> None:
    with pytest.raises(ValueError, match="degree"):
        SphericalHarmonicsEncoding(4)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        SphericalHarmonicsEncoding(3)(torch.zeros(4, 2))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        spherical_harmonics(torch.zeros(4), 2)
