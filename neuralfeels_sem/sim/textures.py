"""Material micro-texture: surface relief as a function of the 3D point in the OBJECT frame.

Each texture maps object-frame points (N, 3) in metres to an outward height (N,) in
metres, so the pattern is fixed to the object and moves with it. A DIGIT resolves about
75 um per pixel, so relief of a few to a few tens of micrometres with periods of 0.2-1 mm
is what makes materials look like themselves through the gel:

- fabric: plain weave of crossing threads (1 mm period) plus fuzz; soft.
- wood: growth rings (distorted, asymmetric early/late wood), long fibres along the
  grain axis (object z) and open pores (vessels: pits 0.2 mm wide, 1-1.5 mm long along
  the grain, densest in the early wood, as in oak or ash); stiff. The pores make wood
  look like wood on every cut: on a face running along the rings, rings and fibres alone
  are parallel lines, like brushed metal.
- metal: fine, faint brushed lines along the object x axis (finer and a third as deep as
  wood's fibres), very little relief; stiff, shiny.
- plastic: smooth with a faint moulded stipple of sparse bumps; slightly compliant.
- anything else: generic smooth surface with faint isotropic roughness.

Random components are drawn once per texture from `seed`, so a texture is deterministic.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.errors import ConfigError

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
    """Growth rings around the object z axis (distorted), fibres along z, and open pores."""

    name = "wood"
    ring_period_m = 1.3e-3
    ring_height_m = 28e-6
    fibre_height_m = 9e-6
    pore_depth_m = 35e-6
    # Pores live in the cells of lattices aligned with the grain (see `pores`).
    pore_cell_m = (0.6e-3, 0.6e-3, 2.0e-3)
    pore_half_width_m = (0.10e-3, 0.16e-3)
    pore_half_length_m = (0.35e-3, 0.75e-3)
    # Chance of a pore in a cell: ring-porous wood has its vessels in the early wood.
    pore_chance_early, pore_chance_late = 0.75, 0.35
    early_wood_share = 0.45

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
        self._pore_salt = np.uint64(self._rng.integers(1, 2**62))
        self._pore_offset = self._rng.uniform(0.0, 1.0, 3)  # lattice not tied to round coordinates

    def _ring_phase(self, points: np.ndarray) -> np.ndarray:
        """Position within the growth ring, 0 (start of early wood) .. 1 (end of late wood)."""
        r = np.hypot(points[:, 0] - self._centre[0], points[:, 1] - self._centre[1])
        r = r + 0.3e-3 * self._distort(points)
        return np.mod(r / self.ring_period_m, 1.0)

    def pores(self, points: np.ndarray, ring_phase: np.ndarray | None = None) -> np.ndarray:
        """(N,) pore profile: 0 outside pores, down to -1 on a pore's axis.

        Pores sit in the cells of two lattices offset by half a cell, at most one per
        cell and wholly inside it, so a point needs only its own cell in each lattice
        (one lattice alone would leave faces along its cell walls without pores).
        `ring_phase` saves recomputing it.
        """
        points = _check_points(points)
        if ring_phase is None:
            ring_phase = self._ring_phase(points)
        # Early wood only: a pore stops where the late wood of its ring starts.
        chance = np.where(
            ring_phase < self.early_wood_share, self.pore_chance_early, self.pore_chance_late
        )
        width = np.asarray(self.pore_half_width_m) / self.pore_cell_m[0]
        length = np.asarray(self.pore_half_length_m) / self.pore_cell_m[2]
        q0 = points.astype(np.float64) / np.asarray(self.pore_cell_m) + self._pore_offset
        depth = np.zeros(len(points))
        for lattice, shift in enumerate((0.0, 0.5)):
            q = q0 + shift
            cell = np.floor(q)
            u = _cell_uniforms(cell.astype(np.int64), self._pore_salt + np.uint64(lattice))
            across, along = _lerp(width, u[:, 0]), _lerp(length, u[:, 1])
            # Squared distance to the pore's axis in units of its half-size, column by column
            # (cheaper than on (N, 3) arrays); the centre keeps the whole pore in its cell.
            d2 = np.zeros(len(q))
            for axis, half in enumerate((across, across, along)):
                centre = cell[:, axis] + half + u[:, 2 + axis] * (1.0 - 2.0 * half)
                offset = (q[:, axis] - centre) / half
                d2 += offset * offset
            there = (d2 < 1.0) & (u[:, 5] < chance)
            np.maximum(depth, np.sqrt(np.clip(1.0 - np.where(there, d2, 1.0), 0.0, 1.0)), out=depth)
        return -depth

    def _relief(self, points: np.ndarray, normal: np.ndarray | None) -> np.ndarray:
        f = self._ring_phase(points)
        # Early wood rises slowly, late wood drops sharply: an asymmetric ring profile.
        ring = f**3 - 0.5
        grain = self.ring_height_m * ring + self.fibre_height_m * self._fibres(points)
        return grain + self.pore_depth_m * self.pores(points, f)


def _lerp(bounds: tuple[float, float], t: np.ndarray) -> np.ndarray:
    return bounds[0] + (bounds[1] - bounds[0]) * t


_PRIMES = tuple(np.uint64(p) for p in (0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9))
_MIX = (np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB))


def _cell_uniforms(cells: np.ndarray, salt: np.uint64) -> np.ndarray:
    """(N, 6) uniform numbers in (0, 1), fixed per integer lattice cell (N, 3) and salt.

    One 64-bit hash per cell (splitmix64 rounds, so every input bit reaches every
    output bit), cut into six 10-bit fields.
    """
    h = np.full(len(cells), salt, dtype=np.uint64)
    bits = np.ascontiguousarray(cells, dtype=np.int64).view(np.uint64)  # two's complement
    for axis, prime in enumerate(_PRIMES):
        h ^= bits[:, axis] * prime
        h ^= h >> np.uint64(30)
        h *= _MIX[0]
        h ^= h >> np.uint64(27)
        h *= _MIX[1]
        h ^= h >> np.uint64(31)
    # Fields read bits 0-59 only, so a signed view (fast to convert to float) reads the same.
    signed = h.view(np.int64)
    out = np.empty((len(cells), 6))
    for k in range(6):
        out[:, k] = (signed >> (10 * k)) & 1023
    out += 0.5
    out /= 1024.0
    return out


class MetalTexture(MicroTexture):
    """Fine, faint brushed lines along the object x axis; almost flat.

    A brushed finish is finer and shallower than wood's fibres (0.15-0.4 mm, 9 um): its
    lines sit at the finest period a DIGIT still resolves, a third of the fibres' relief.
    """

    name = "metal"
    line_height_m = 3e-6
    line_wavelength_m = (0.15e-3, 0.3e-3)

    def __init__(self, seed: int = 0, scale: float = 1.0) -> None:
        super().__init__(seed, scale)
        self._lines = _Waves.random(
            self._rng, 8, self.line_wavelength_m, plane_normal=np.array([1.0, 0.0, 0.0])
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
