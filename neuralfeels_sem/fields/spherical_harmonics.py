"""Real spherical-harmonics encoding of unit directions (bands l = 0..degree).

`degree` is the highest band, so the encoding has (degree + 1)^2 outputs: degree 3 gives
the paper's 16 coefficients. (tiny-cuda-nn counts differently: its "degree" is the number
of bands, so its degree 4 is this degree 3.) Constants are the orthonormal real SH on the
unit sphere, the same basis and sign convention as nerfstudio's `components_from_spherical_harmonics`.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

MAX_DEGREE = 3

_C0 = 0.28209479177387814  # 1 / (2 sqrt(pi))
_C1 = 0.4886025119029199  # sqrt(3 / (4 pi))
_C2 = (1.0925484305920792, 0.9461746957575601, 0.31539156525252005, 0.5462742152960396)
_C3 = (
    0.5900435899266435,
    2.890611442640554,
    0.4570457994644658,
    0.3731763325901154,
    1.445305721320277,
)


def num_sh_coefficients(degree: int) -> int:
    return (degree + 1) ** 2


def spherical_harmonics(directions: Tensor, degree: int) -> Tensor:
    """Real SH basis of unit `directions` (..., 3) up to band `degree` -> (..., (degree+1)^2).

    Directions are used as given (normalise first): the polynomials are only the SH basis
    on the unit sphere.
    """
    if directions.shape[-1] != 3:
        raise ValueError(f"directions must have shape (..., 3), got {tuple(directions.shape)}")
    if not 0 <= degree <= MAX_DEGREE:
        raise ValueError(f"sh degree {degree} must be in [0, {MAX_DEGREE}]")
    x, y, z = directions.unbind(-1)
    out = [torch.full_like(x, _C0)]
    if degree >= 1:
        out += [_C1 * y, _C1 * z, _C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        out += [
            _C2[0] * x * y,
            _C2[0] * y * z,
            _C2[1] * zz - _C2[2],
            _C2[0] * x * z,
            _C2[3] * (xx - yy),
        ]
    if degree >= 3:
        out += [
            _C3[0] * y * (3 * xx - yy),
            _C3[1] * x * y * z,
            _C3[2] * y * (5 * zz - 1),
            _C3[3] * z * (5 * zz - 3),
            _C3[2] * x * (5 * zz - 1),
            _C3[4] * z * (xx - yy),
            _C3[0] * x * (xx - 3 * yy),
        ]
    return torch.stack(out, dim=-1)


class SphericalHarmonicsEncoding(nn.Module):
    """Encode directions (N, 3) with the real SH basis; inputs are normalised here."""

    def __init__(self, degree: int = 3, eps: float = 1e-9) -> None:
        super().__init__()
        if not 0 <= degree <= MAX_DEGREE:
            raise ValueError(f"sh degree {degree} must be in [0, {MAX_DEGREE}]")
        self.degree = degree
        self.eps = eps

    @property
    def out_dim(self) -> int:
        return num_sh_coefficients(self.degree)

    def forward(self, directions: Tensor) -> Tensor:
        if directions.ndim != 2 or directions.shape[1] != 3:
            raise ValueError(f"directions must have shape (N, 3), got {tuple(directions.shape)}")
        # A zero vector (a query exactly at the centre) maps to the zero direction; the
        # constant band still carries it.
        unit = directions / directions.norm(dim=-1, keepdim=True).clamp_min(self.eps)
        return spherical_harmonics(unit, self.degree)
