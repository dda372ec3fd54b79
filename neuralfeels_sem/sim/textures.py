"""Material micro-texture: surface relief as a function of the 3D point in the OBJECT frame.

Each texture maps object-frame points (N, 3) in metres to an outward height (N,) in
metres, so the pattern is fixed to the object and moves with it. A DIGIT resolves about
75 um per pixel, so relief of a few to a few tens of micrometres with periods of 0.2-1 mm
is what makes materials look like themselves through the gel:

- fabric: plain weave of crossing threads (1 mm period) plus fuzz; soft.
- wood: growth rings (distorted, asymmetric early/late wood) and long fibres along the
  grain axis (object z); stiff.
- metal: fine brushed lines along the object x axis, very little relief; stiff, shiny.
- plastic: smooth with a faint moulded stipple of sparse bumps; slightly compliant.
- anything else: generic smooth surface with faint isotropic roughness.

Random components are drawn once per texture from `seed`, so a texture is deterministic.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.errors import ConfigError

# How soft each material is, 0 (rigid) .. 1 (fabric): deeper, wider, blurrier imprints.
DEFAULT_COMPLIANCE: dict[str, float] = {"fabric": 1.0, "plastic": 0.15, "wood": 0.05, "metal": 0.0}
# Specular strength of the object under the gel (the gel's paint mostly hides it; metal shows a bit).
DEFAULT_SPECULAR: dict[str, float] = {"metal": 0.6, "plastic": 0.25}
GENERIC_COMPLIANCE = 0.1


def _check_points(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"texture points must have shape (N, 3), got {points.shape}")
    return points.astype(np.float32, copy=False)


@dataclass(frozen=True)
class _Waves:
    """A sum of plane waves sum_i a_i sin(k_i . p + phi_i), normalised to unit std."""

    k: np.ndarray  # (M, 3) wave vectors, rad/m
    phase: np.ndarray  # (M,)
    amp: np.ndarray  # (M,)

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        count: int,
        wavelength_m: tuple[float, float],
        plane_normal: np.ndarray | None = None,
    ) -> _Waves:
        """Random directions (isotropic, or within the plane orthogonal to `plane_normal`)."""
        dirs = rng.normal(size=(count, 3))
        if plane_normal is not None:
            n = np.asarray(plane_normal, float) / np.linalg.norm(plane_normal)
            dirs -= np.outer(dirs @ n, n)
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        lam = np.exp(rng.uniform(np.log(wavelength_m[0]), np.log(wavelength_m[1]), count))
        amp = rng.uniform(0.5, 1.0, count)
        amp /= np.sqrt(0.5 * np.sum(amp**2))  # unit standard deviation overall
        return cls(
            (dirs * (2 * np.pi / lam)[:, None]).astype(np.float32),
            rng.uniform(0, 2 * np.pi, count).astype(np.float32),
            amp.astype(np.float32),
        )

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.sin(points @ self.k.T + self.phase) @ self.amp


class MicroTexture:
    """Base: outward relief height (metres) at object-frame points."""

    name = "generic"

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        if scale < 0:
            raise ValueError(f"texture scale must be >= 0, got {scale}")
        self.scale = float(scale)
        # Stable per-material stream: the same seed gives different patterns per material.
        self._rng = np.random.default_rng([seed, zlib.crc32(self.name.encode())])
        self._rough = _Waves.random(self._rng, 6, (0.3e-3, 0.8e-3))

    def height(self, points: np.ndarray, normal: np.ndarray | None = None) -> np.ndarray:
        """(N,) outward relief in metres at (N, 3) object-frame points.

        `normal` is the (approximate) outward surface normal in the object frame at
        these points; textures that are projected onto the surface (the weave) use it.
        """
        points = _check_points(points)
        if self.scale == 0 or len(points) == 0:
            return np.zeros(len(points), np.float32)
        return (self.scale * self._relief(points, normal)).astype(np.float32)

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        return 1.0e-6 * self._rough(points)


class FabricTexture(MicroTexture):
    """Plain weave: warp and weft threads alternately over and under, plus fuzz."""

    name = "fabric"
    period_m = 1.0e-3
    thread_height_m = 45e-6
    fuzz_m = 6e-6

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        super().__init__(seed, scale)
        self._fuzz = _Waves.random(self._rng, 5, (0.12e-3, 0.35e-3))
        self._angle = float(self._rng.uniform(0, np.pi / 2))  # weave orientation on each plane

    def _weave(self, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Unit-height plain weave on plane coordinates (s, t), float32.

        Warp threads run along a, weft along b (both in thread periods). Thread profile:
        |sin(pi b)| (round, zero between threads); over/under: a warp thread is up where
        sin(pi a) has the sign of its own index parity, sign(sin(pi b)) = (-1)^floor(b),
        so warp = |sb| (1 + sa sign(sb)) / 2 = (|sb| + sa sb) / 2 and weft the opposite.
        """
        c, sn = (
            np.float32(np.cos(self._angle) / self.period_m),
            np.float32(np.sin(self._angle) / self.period_m),
        )
        sa = np.sin(np.float32(np.pi) * (c * s + sn * t))
        sb = np.sin(np.float32(np.pi) * (c * t - sn * s))
        cross = sa * sb
        return np.float32(0.5) * np.maximum(np.abs(sb) + cross, np.abs(sa) - cross)

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        # Tri-planar projection: the weave is a 2D pattern; blend the three axis planes
        # by how much the surface faces each axis.
        n = np.array([0.0, 0.0, 1.0]) if normal is None else np.abs(np.asarray(normal, np.float64))
        w = n**4
        w /= w.sum()
        weave = np.zeros(len(points), np.float32)
        for axis in range(3):
            if w[axis] < 0.02:
                continue
            s, t = np.delete(points, axis, axis=1).T
            weave += np.float32(w[axis]) * self._weave(s, t)
        return self.thread_height_m * weave + self.fuzz_m * self._fuzz(points)


class WoodTexture(MicroTexture):
    """Growth rings around the object z axis (distorted) plus fibres running along z."""

    name = "wood"
    ring_period_m = 1.3e-3
    ring_height_m = 28e-6
    fibre_height_m = 9e-6

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        super().__init__(seed, scale)
        # Pith off the object centre, so rings cross any surface at varied angles.
        self._centre = self._rng.uniform(-0.02, 0.02, 2).astype(np.float32)
        # Ring wobble and fibres vary only across the grain (x, y): wood is straight along z.
        self._distort = _Waves.random(
            self._rng, 4, (3e-3, 8e-3), plane_normal=np.array([0.0, 0.0, 1.0])
        )
        self._fibres = _Waves.random(
            self._rng, 6, (0.15e-3, 0.4e-3), plane_normal=np.array([0.0, 0.0, 1.0])
        )

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        r = np.hypot(points[:, 0] - self._centre[0], points[:, 1] - self._centre[1])
        r = r + 0.3e-3 * self._distort(points)
        f = np.mod(r / self.ring_period_m, 1.0)
        # Early wood rises slowly, late wood drops sharply: an asymmetric ring profile.
        ring = f**3 - 0.5
        return self.ring_height_m * ring + self.fibre_height_m * self._fibres(points)


class MetalTexture(MicroTexture):
    """Fine brushed lines along the object x axis; almost flat."""

    name = "metal"
    line_height_m = 6e-6

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        super().__init__(seed, scale)
        self._lines = _Waves.random(
            self._rng, 8, (0.15e-3, 0.6e-3), plane_normal=np.array([1.0, 0.0, 0.0])
        )

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        return self.line_height_m * self._lines(points)


class PlasticTexture(MicroTexture):
    """Smooth, with a faint moulded stipple: sparse rounded bumps."""

    name = "plastic"
    bump_height_m = 14e-6

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        super().__init__(seed, scale)
        self._stipple = _Waves.random(self._rng, 8, (0.35e-3, 0.7e-3))

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        return self.bump_height_m * np.maximum(self._stipple(points) - 0.9, 0.0)


_TEXTURES: dict[str, type[MicroTexture]] = {
    cls.name: cls for cls in (FabricTexture, WoodTexture, MetalTexture, PlasticTexture)
}


def texture_for(material: str, seed: int = 0, scale: float = 1.0) -> MicroTexture:
    """The texture of a material by name (case-insensitive); unknown names get a generic smooth one."""
    return _TEXTURES.get(material.lower(), MicroTexture)(seed=seed, scale=scale)


def compliance_for(material: str, overrides: dict[str, float] | None = None) -> float:
    """Compliance 0..1 of a material by name; `overrides` (by name) wins over the defaults."""
    key = material.lower()
    if overrides and key in {k.lower() for k in overrides}:
        value = {k.lower(): v for k, v in overrides.items()}[key]
    else:
        value = DEFAULT_COMPLIANCE.get(key, GENERIC_COMPLIANCE)
    if not 0.0 <= value <= 1.0:
        raise ConfigError(
            f"sensor.tactile.compliance.{material}={value} must be in [0, 1] (0 rigid, 1 fabric-soft)"
        )
    return float(value)


def specular_for(material: str) -> float:
    return DEFAULT_SPECULAR.get(material.lower(), 0.0)
