"""Recipes for the shipped objects: a smooth implicit shape plus material regions.

Coordinates are metres, z up, the object's front towards +x. `library.py` meshes a
recipe, labels its faces and centres it; nothing here is random except the yarn
ball's winding, which uses a fixed seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from neuralfeels_sem.objects import sdf as S
from neuralfeels_sem.objects.materials import IGNORE_NAME
from neuralfeels_sem.objects.regions import Region

SEAM = 0.001  # faces this close to a change of material are ignored (m)
BOTTOM_BAND = 0.0015  # faces this close to a flat bottom are ignored (the object rests there)


@dataclass(frozen=True)
class Recipe:
    name: str
    description: str
    shape: S.SDF
    lower: tuple[float, float, float]  # a box containing the whole solid
    upper: tuple[float, float, float]
    base_material: str
    regions: list[Region] = field(default_factory=list)
    seam_width: float = SEAM
    target_faces: int = 20_000  # mesh resolution (library.py picks the grid spacing)


def _bottom(z: float) -> Region:
    return Region(S.half_space_below(z + BOTTOM_BAND), IGNORE_NAME)


def _inflate(f: S.SDF, by: float) -> S.SDF:
    return lambda p: f(p) - by


def _surface_point(shape: S.SDF, direction: tuple[float, float, float]) -> tuple:
    """Where the ray from the origin (inside `shape`) along `direction` leaves the surface."""
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    inside, outside = 0.0, 0.2
    for _ in range(50):  # bisection to well under a micrometre
        mid = 0.5 * (inside + outside)
        if shape((mid * d)[None])[0] < 0:
            inside = mid
        else:
            outside = mid
    return tuple(inside * d)


def _laid_along_y(f: S.SDF) -> S.SDF:
    """An upright shape (long axis z) laid down with its long axis along y, its x up.

    Upright (x, y, z) = laid (z, x, y): so the rounded cylinders round z serve lying parts.
    """
    return lambda p: f(p[:, [2, 0, 1]])


def _on_sphere(center: np.ndarray, radius: float, direction: tuple[float, float, float]) -> tuple:
    d = np.asarray(direction, dtype=np.float64)
    return tuple(center + radius * d / np.linalg.norm(d))


def plushie() -> Recipe:
    """A sitting teddy bear: fabric body, plastic eyes and nose, a flat plastic tag on its back."""
    head_c = np.array([0.0, 0.0, 0.040])
    head_r = 0.022
    body = S.smooth_union(
        [
            S.ellipsoid((0.0, 0.0, 0.0), (0.026, 0.030, 0.032)),
            S.sphere(tuple(head_c), head_r),
            S.sphere((-0.002, 0.017, 0.058), 0.008),  # ears
            S.sphere((-0.002, -0.017, 0.058), 0.008),
            S.ellipsoid((0.019, 0.0, 0.035), (0.009, 0.011, 0.008)),  # snout
            S.capsule((0.005, 0.024, 0.012), (0.020, 0.033, -0.008), 0.008),  # arms
            S.capsule((0.005, -0.024, 0.012), (0.020, -0.033, -0.008), 0.008),
            S.capsule((0.010, 0.015, -0.025), (0.032, 0.017, -0.030), 0.009),  # legs
            S.capsule((0.010, -0.015, -0.025), (0.032, -0.017, -0.030), 0.009),
        ],
        k=0.006,
    )
    eye_l = S.sphere(_on_sphere(head_c, head_r - 0.001, (0.8, 0.38, 0.35)), 0.0045)
    eye_r = S.sphere(_on_sphere(head_c, head_r - 0.001, (0.8, -0.38, 0.35)), 0.0045)
    nose = S.ellipsoid((0.0275, 0.0, 0.038), (0.0035, 0.005, 0.0035))
    tag = S.rounded_box((-0.0265, 0.0, 0.0), (0.002, 0.012, 0.009), 0.0015)
    shape = S.smooth_union([body, eye_l, eye_r, nose, tag], k=0.001)
    # Grown a little so that the blended fillet at a feature's foot is not fabric.
    regions = [Region(_inflate(f, 0.0003), "plastic") for f in (eye_l, eye_r, nose, tag)]
    return Recipe(
        "plushie",
        "sitting teddy bear, 10.5 cm: fabric, plastic eyes, nose and back tag",
        shape,
        (-0.035, -0.05, -0.045),
        (0.05, 0.05, 0.07),
        "fabric",
        regions,
    )


def _toy_shape() -> tuple[S.SDF, float]:
    """The paper's plastic toy, here a bath-duck-like figure with a flat bottom."""
    z_bottom = -0.016
    shape = S.smooth_union(
        [
            S.ellipsoid((0.0, 0.0, 0.0), (0.038, 0.028, 0.024)),
            S.sphere((0.018, 0.0, 0.035), 0.020),  # head
            S.ellipsoid((0.040, 0.0, 0.032), (0.012, 0.009, 0.0045)),  # beak
            S.ellipsoid((-0.036, 0.0, 0.012), (0.010, 0.012, 0.006)),  # tail
        ],
        k=0.008,
    )
    return S.smooth_intersection(shape, S.half_space_above(z_bottom), k=0.002), z_bottom


_TOY_BOX = ((-0.05, -0.035, -0.02), (0.06, 0.035, 0.06))


def plastic_toy() -> Recipe:
    shape, z_bottom = _toy_shape()
    return Recipe(
        "plastic_toy",
        "plastic duck-like toy, 9 cm",
        shape,
        *_TOY_BOX,
        "plastic",
        [_bottom(z_bottom)],
    )


def patched_toy() -> Recipe:
    """The plastic toy with a fabric 'vest' wrapped round the back of its body."""
    shape, z_bottom = _toy_shape()
    vest = S.rounded_box((-0.018, 0.0, 0.004), (0.032, 0.04, 0.02), 0.004)
    return Recipe(
        "patched_toy",
        "the plastic toy partly covered by a fabric patch round its back, 9 cm",
        shape,
        *_TOY_BOX,
        "plastic",
        [Region(vest, "fabric"), _bottom(z_bottom)],
    )


def fabric_toy() -> Recipe:
    """A toy completely covered with fabric: a sitting bunny."""
    z_bottom = -0.028
    shape = S.smooth_union(
        [
            S.ellipsoid((0.0, 0.0, 0.0), (0.024, 0.022, 0.030)),
            S.sphere((0.006, 0.0, 0.038), 0.018),  # head
            S.capsule((0.002, 0.007, 0.05), (-0.004, 0.012, 0.074), 0.0055),  # ears
            S.capsule((0.002, -0.007, 0.05), (-0.004, -0.012, 0.074), 0.0055),
            S.sphere((-0.024, 0.0, -0.012), 0.008),  # tail
            S.ellipsoid((0.016, 0.012, -0.026), (0.014, 0.008, 0.006)),  # feet
            S.ellipsoid((0.016, -0.012, -0.026), (0.014, 0.008, 0.006)),
        ],
        k=0.006,
    )
    shape = S.smooth_intersection(shape, S.half_space_above(z_bottom), k=0.002)
    return Recipe(
        "fabric_toy",
        "sitting bunny covered in fabric, 10.5 cm",
        shape,
        (-0.04, -0.035, -0.035),
        (0.045, 0.035, 0.085),
        "fabric",
        [_bottom(z_bottom)],
    )


def _yarn_offset(radius: float, wavelength: float, amplitude: float, seed: int = 7) -> Callable:
    """Strands wound in patches: each patch has its own winding axis, blended smoothly."""
    rng = np.random.default_rng(seed)
    lobes = rng.normal(size=(8, 3))
    lobes /= np.linalg.norm(lobes, axis=1, keepdims=True)
    axes = rng.normal(size=(8, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)

    def offset(p: np.ndarray) -> np.ndarray:
        u = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-9)
        logits = 6.0 * (u @ lobes.T)
        w = np.exp(logits - logits.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        # Rings round each axis: arc length from the axis' equator, cut into strands.
        arc = radius * np.arcsin(np.clip(u @ axes.T, -1.0, 1.0))
        strands = 0.5 * (1.0 + np.cos(2 * np.pi * arc / wavelength))
        return amplitude * (w * strands).sum(axis=1)

    return offset


def yarn_ball() -> Recipe:
    radius = 0.034
    shape = S.displaced(
        S.sphere((0.0, 0.0, 0.0), radius), _yarn_offset(radius, 0.006, 0.0006), 0.0006
    )
    return Recipe(
        "yarn_ball",
        "ball of wound yarn, 7 cm",
        shape,
        (-0.04,) * 3,
        (0.04,) * 3,
        "fabric",
        # Finer grid (1.3 mm) so that each 6 mm strand spans between four and five cells.
        target_faces=28_000,
    )


def candle_holder() -> Recipe:
    """A turned wooden candle holder: foot, beaded stem, cup with a candle socket."""
    solid = S.smooth_union(
        [
            S.rounded_cylinder(0.0, 0.012, 0.035, 0.004),  # foot
            S.rounded_cylinder(0.008, 0.072, 0.011, 0.002),  # stem
            S.torus(0.030, 0.011, 0.006),  # beads
            S.torus(0.052, 0.011, 0.005),
            S.rounded_cylinder(0.066, 0.090, 0.022, 0.004),  # cup
        ],
        k=0.005,
    )
    socket = S.rounded_cylinder(0.074, 0.12, 0.0115, 0.001)
    shape = S.smooth_difference(solid, socket, k=0.0015)
    # No fingertip fits in the 23 mm socket: leave its inside out of the evaluation.
    inside_socket = S.rounded_cylinder(0.072, 0.12, 0.0125, 0.001)
    return Recipe(
        "candle_holder",
        "turned wooden candle holder with a candle socket, 9 cm",
        shape,
        (-0.04, -0.04, -0.005),
        (0.04, 0.04, 0.095),
        "wood",
        [Region(inside_socket, IGNORE_NAME), _bottom(0.0)],
    )


def powder_shaker() -> Recipe:
    """A stainless-steel powder shaker: cylinder, a lid with a lip, a domed top and a knob."""
    shape = S.smooth_union(
        [
            S.rounded_cylinder(0.0, 0.075, 0.026, 0.003),  # can
            S.rounded_cylinder(0.072, 0.086, 0.0275, 0.003),  # lid
            S.ellipsoid((0.0, 0.0, 0.085), (0.024, 0.024, 0.010)),  # dome
            S.sphere((0.0, 0.0, 0.0965), 0.005),  # knob
        ],
        k=0.002,
    )
    return Recipe(
        "powder_shaker",
        "stainless-steel powder shaker, 10 cm",
        shape,
        (-0.035, -0.035, -0.005),
        (0.035, 0.035, 0.106),
        "metal",
        [_bottom(0.0)],
    )


def patchwork() -> Recipe:
    """A pebble quilted from all four materials in patches of different sizes.

    Plastic (the base) is left in two pieces between the patches: wood round the back
    left, fabric over the top, metal on the front right and a small metal badge on the
    front left that one DIGIT press covers. The patches sit where the rig's fingers reach
    as it turns the pebble about both of its default axes.
    """
    z_bottom = -0.025
    body = S.smooth_union(
        [
            S.ellipsoid((0.0, 0.0, 0.0), (0.046, 0.036, 0.030)),
            S.ellipsoid((0.010, 0.004, 0.010), (0.030, 0.028, 0.026)),  # a hump, front top
        ],
        k=0.01,
    )
    shape = S.smooth_intersection(body, S.half_space_above(z_bottom), k=0.003)
    # Each patch is a ball centred on the surface: it cuts a roundish patch out of it.
    # The badge: 1.4 x 2 cm inside its seam (2 cm^2), within one press of the 1.8 x 2.4 cm gel.
    badge = S.ellipsoid(_surface_point(shape, (1.0, -0.5, 0.05)), (0.008, 0.008, 0.011))
    regions = [
        Region(S.sphere(_surface_point(shape, (-1.0, -0.8, -0.1)), 0.040), "wood"),
        Region(S.sphere(_surface_point(shape, (-0.2, 0.5, 1.0)), 0.036), "fabric"),
        Region(S.sphere(_surface_point(shape, (0.6, 1.0, -0.1)), 0.030), "metal"),
        Region(badge, "metal"),
        _bottom(z_bottom),
    ]
    return Recipe(
        "patchwork",
        "pebble quilted from plastic, wood, fabric and metal patches (one a 2 cm^2 badge), 9 cm",
        shape,
        (-0.05, -0.04, -0.03),
        (0.05, 0.04, 0.045),
        "plastic",
        regions,
    )


def kitchen_tool() -> Recipe:
    """A spoon-like kitchen tool lying along y: wooden handle, plastic grip band, metal head.

    Built upright (handle end at z = 0, head up) and laid down along y, the head towards
    +y. Handle and head are cut flat underneath where the tool rests (ignored). A chunky
    3 cm handle, 3.4 cm at the grip band, gives the fingertips room. 13.7 cm long: lying
    down it turns in the hand about both default axes with every material in reach
    (upright, only the middle band was touched while it turned about z).
    """
    handle_r, head_z = 0.015, 0.104
    head = (0.012, 0.023, 0.028)  # half thickness, half width, half length
    grip = (0.028, 0.055)  # along the handle from its end
    upright = S.smooth_union(
        [
            S.rounded_cylinder(0.0, 0.02, handle_r, 0.003),  # flat handle end
            S.capsule((0.0, 0.0, 0.01), (0.0, 0.0, head_z - 0.02), handle_r),
            S.rounded_cylinder(grip[0], grip[1], 0.017, 0.003),  # raised grip band
            # The head hangs 3 mm lower than the handle so both rest on the table.
            S.ellipsoid((-0.003, 0.0, head_z), head),
        ],
        k=0.006,
    )
    handle_end = -0.068  # y of the handle's end: centres the tool along y
    lift = np.array([0.0, 0.0, -handle_end])
    tool = _laid_along_y(lambda p: upright(p + lift))
    z_bottom = -0.0145
    shape = S.smooth_intersection(tool, S.half_space_above(z_bottom), k=0.002)
    band = S.rounded_cylinder(grip[0] - 0.002, grip[1] + 0.002, 0.05, 0.001)
    head_start = handle_end + head_z - head[2] + 0.004  # the wooden neck ends just inside the head
    regions = [
        Region(_laid_along_y(lambda p: band(p + lift)), "plastic"),
        Region(lambda p: head_start - p[:, 1], "metal"),
        _bottom(z_bottom),
    ]
    return Recipe(
        "kitchen_tool",
        "spoon-like kitchen tool lying along y: wooden handle, plastic grip band, metal head, 13.7 cm",
        shape,
        (-0.03, handle_end - 0.005, z_bottom - 0.003),
        (0.03, handle_end + head_z + head[2] + 0.01, 0.025),
        "wood",
        regions,
    )


RECIPES: dict[str, Callable[[], Recipe]] = {
    "plushie": plushie,
    "patched_toy": patched_toy,
    "fabric_toy": fabric_toy,
    "yarn_ball": yarn_ball,
    "candle_holder": candle_holder,
    "powder_shaker": powder_shaker,
    "plastic_toy": plastic_toy,
    "patchwork": patchwork,
    "kitchen_tool": kitchen_tool,
}
