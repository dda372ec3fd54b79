"""Per-object, per-finger contact fractions of the simulated rig, from the DIGITs' ground truth.

For each object the rig runs `duration_s` at `fps`; every frame each finger's DIGIT
renders its ground-truth contact mask (the renderer's depth pass only, no shading)
and the finger counts as in contact when at least `min_pixels` gel pixels touch.
Also reported: how often contact is re-made (gaiting), the rig's own `touching`
flag and press depth, the share of the surface within 1 cm of a touched point, the
closest approach between geoms of different fingers (DIGIT bodies and links; negative =
overlap), the closest approach of gel centres, the worst joint-limit violation, and the
frames where a finger ends the step inside the object (the object reaching deeper into its
gel than the gel can be pressed, MAX_PENETRATION_M: no real finger gets there, and its
contact points land inside the object).

    python -m neuralfeels_sem.bench.finger_contacts                      # every shipped object
    python -m neuralfeels_sem.bench.finger_contacts --objects candle_holder --duration 5
    python -m neuralfeels_sem.bench.finger_contacts --objects random:103 --duration 30 --seed 1

Not a bench_* module, so `make bench` does not run it (about half a minute per object).
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import mujoco
import numpy as np
from scipy.spatial import cKDTree

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.digit import GEL_DISTANCE_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.objects.procedural import RECIPES
from neuralfeels_sem.objects.random_object import make_random_object
from neuralfeels_sem.sim.rig import SimRig
from neuralfeels_sem.sim.trajectory import GRASP_HEIGHTS

CLASSES = tuple(DEFAULT_MATERIALS)
MIN_PIXELS = 50  # contact pixels (of 76,800) for a frame to count as a touch


@dataclass
class ContactReport:
    object: str
    frames: int
    contact_fraction: dict[str, float]  # share of frames with >= min_pixels contact pixels
    remakes: dict[str, int]  # no-contact -> contact transitions (gaiting)
    touching_fraction: dict[str, float]  # the rig's own touching flag
    mean_contact_px: dict[str, float]  # mean contact area over frames in contact
    mean_press_mm: dict[str, float]  # the rig's press depth while touching
    inside_frames: dict[str, list[int]]  # frames the finger ends inside the object
    deepest_press_mm: dict[str, float]  # the object's deepest reach into the gel, any phase
    min_finger_gap_m: dict[str, float]  # closest approach per finger pair (geom distance)
    min_gel_distance_m: dict[str, float]  # closest gel centres per finger pair
    joint_limit_violation_rad: float  # worst excursion past a joint limit (0 = none)
    coverage: float  # share of the surface within 1 cm of a touched point (rig's touches)
    rig_updates_per_s: float


def finger_geoms(model: mujoco.MjModel) -> dict[str, list[int]]:
    """Geom ids (links and DIGIT body) of each finger."""
    return {
        f: [g for g in range(model.ngeom) if (model.geom(g).name or "").startswith(f"{f}_")]
        for f in FINGERS
    }


def finger_gaps(model: mujoco.MjModel, data: mujoco.MjData, geoms: dict[str, list[int]]) -> dict:
    """Smallest signed distance between any geoms of two fingers, per finger pair (m)."""
    gaps = {}
    fromto = np.zeros(6)
    for a, b in itertools.combinations(FINGERS, 2):
        gaps[f"{a}-{b}"] = min(
            mujoco.mj_geomDistance(model, data, ga, gb, 0.05, fromto)
            for ga in geoms[a]
            for gb in geoms[b]
        )
    return gaps


@dataclass
class _Tally:
    """What measure() gathers frame by frame, for n frames of the four fingers."""

    contact: np.ndarray  # (n, fingers) contact mask has >= min_pixels pixels
    touching: np.ndarray  # (n, fingers) the rig's touching flag
    area: np.ndarray  # (n, fingers) contact pixels
    press: np.ndarray  # (n, fingers) the rig's press depth (m)
    gaps: dict[str, float]  # closest geom distance per finger pair
    gel_distance: dict[str, float]  # closest gel centres per finger pair
    violation: float = 0.0
    rig_time: float = 0.0
    touched: list = field(default_factory=list)

    @classmethod
    def empty(cls, n: int) -> _Tally:
        gaps = {f"{a}-{b}": np.inf for a, b in itertools.combinations(FINGERS, 2)}
        return cls(
            contact=np.zeros((n, len(FINGERS)), bool),
            touching=np.zeros((n, len(FINGERS)), bool),
            area=np.zeros((n, len(FINGERS))),
            press=np.zeros((n, len(FINGERS))),
            gaps=gaps,
            gel_distance=dict(gaps),
        )


def _tally_fingers(
    tally: _Tally, i: int, state, limits: dict, renderers: dict, render: bool, min_pixels: int
) -> None:
    """Frame i per finger: touching flag, press, joint-limit excursion and (render) contact area."""
    for j, f in enumerate(FINGERS):
        tally.touching[i, j] = state.touching.get(f, False)
        tally.press[i, j] = state.press_m.get(f, 0.0)
        q = state.joint_positions[4 * j : 4 * j + 4]
        lo, hi = limits[f][:, 0], limits[f][:, 1]
        tally.violation = max(tally.violation, float(np.max(np.maximum(lo - q, q - hi))))
        if render:
            depth, _ = renderers[f].render_geometry(state.world_T_object, state.world_T_sensor[f])
            px = int(np.count_nonzero((depth > 0) & (depth < GEL_DISTANCE_M)))
            tally.area[i, j] = px
            tally.contact[i, j] = px >= min_pixels


def _tally_pairs(
    tally: _Tally, model: mujoco.MjModel, data: mujoco.MjData, geoms: dict, state
) -> None:
    """The frame's closest approach per finger pair: geoms and gel centres."""
    for pair, gap in finger_gaps(model, data, geoms).items():
        tally.gaps[pair] = min(tally.gaps[pair], gap)
    gels = {f: state.world_T_sensor[f] @ [0.0, 0.0, GEL_DISTANCE_M, 1.0] for f in FINGERS}
    for a, b in itertools.combinations(FINGERS, 2):
        d = float(np.linalg.norm(gels[a][:3] - gels[b][:3]))
        tally.gel_distance[f"{a}-{b}"] = min(tally.gel_distance[f"{a}-{b}"], d)


def _coverage(obj: MaterialObject, touched: list) -> float:
    """Share of 4000 surface samples within 1 cm of a touched point."""
    if not touched:
        return 0.0
    samples, _, _ = obj.sample_surface(4000, seed=0)
    return float((cKDTree(np.array(touched)).query(samples)[0] < 0.01).mean())


def _report(name: str, obj: MaterialObject, n: int, tally: _Tally, render: bool) -> ContactReport:
    """The rounded per-finger and per-pair figures; without renders contact = touching."""
    contact = tally.contact if render else tally.touching
    touching, area, press = tally.touching, tally.area, tally.press
    remakes = np.count_nonzero(~contact[:-1] & contact[1:], axis=0)
    coverage = _coverage(obj, tally.touched)
    return ContactReport(
        object=name,
        frames=n,
        contact_fraction={f: round(float(contact[:, j].mean()), 3) for j, f in enumerate(FINGERS)},
        remakes={f: int(remakes[j]) for j, f in enumerate(FINGERS)},
        touching_fraction={
            f: round(float(touching[:, j].mean()), 3) for j, f in enumerate(FINGERS)
        },
        mean_contact_px={
            f: round(float(area[contact[:, j], j].mean()), 1) if contact[:, j].any() else 0.0
            for j, f in enumerate(FINGERS)
        },
        mean_press_mm={
            f: round(1000 * float(press[touching[:, j], j].mean()), 2)
            if touching[:, j].any()
            else 0.0
            for j, f in enumerate(FINGERS)
        },
        inside_frames={
            f: np.flatnonzero(press[:, j] > MAX_PENETRATION_M).tolist()
            for j, f in enumerate(FINGERS)
        },
        deepest_press_mm={
            f: round(1000 * float(press[:, j].max()), 2) for j, f in enumerate(FINGERS)
        },
        min_finger_gap_m={k: round(float(v), 4) for k, v in tally.gaps.items()},
        min_gel_distance_m={k: round(v, 4) for k, v in tally.gel_distance.items()},
        joint_limit_violation_rad=round(max(tally.violation, 0.0), 6),
        coverage=round(coverage, 3),
        rig_updates_per_s=round(n / tally.rig_time, 2),
    )


def measure(
    name: str | MaterialObject,
    duration_s: float = 10.0,
    fps: float = 10.0,
    seed: int = 0,
    min_pixels: int = MIN_PIXELS,
    render: bool = True,
    rig_options: dict | None = None,
) -> ContactReport:
    """Run the rig on shipped object `name` (`random:K`: generated object K; or an object);
    `render=False`: no DIGIT renders.

    Without renders the contact fraction is the rig's touching flag.
    """
    obj = name if isinstance(name, MaterialObject) else _object(name)
    name = obj.name
    rig = SimRig(obj, seed=seed, **(rig_options or {}))
    rig.open()
    renderers = {}
    if render:
        from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

        renderers = {f: DigitRenderer(obj, seed=seed) for f in FINGERS}
    model, data = rig.scene.model, rig.scene.data
    geoms = finger_geoms(model)
    limits = rig.ik.limits
    n = int(np.floor(duration_s * fps + 1e-9))
    tally = _Tally.empty(n)
    for i in range(n):
        start = time.perf_counter()
        state = rig.state_at(i / fps)
        tally.rig_time += time.perf_counter() - start
        tally.touched += [p for p in state.contact_point.values() if p is not None]
        _tally_fingers(tally, i, state, limits, renderers, render, min_pixels)
        _tally_pairs(tally, model, data, geoms, state)
    for renderer in renderers.values():
        renderer.close()
    return _report(name, obj, n, tally, render)


def _object(name: str) -> MaterialObject:
    """A shipped object by name, or generated object K as `random:K`."""
    if name.startswith("random:"):
        seed = name.split(":", 1)[1]
        if not seed.isdigit():
            raise ValueError(f"--objects {name}: a generated object is random:K, K a seed >= 0")
        return make_random_object(int(seed), CLASSES)
    return make_object(name, CLASSES)


def table(reports: Sequence[ContactReport]) -> str:
    """Markdown table of contact fractions (index / middle / ring / thumb) per object."""
    lines = [
        "| object | contact fraction, index / middle / ring / thumb | re-touches | closest fingers (mm) | closest gel centres (mm) | frames inside the object |",
        "|---|---|---|---|---|---|",
    ]
    for r in reports:
        frac = " / ".join(f"{r.contact_fraction[f]:.2f}" for f in FINGERS)
        remakes = " / ".join(str(r.remakes[f]) for f in FINGERS)
        pair = min(r.min_finger_gap_m, key=r.min_finger_gap_m.get)
        near = min(r.min_gel_distance_m, key=r.min_gel_distance_m.get)
        lines.append(
            f"| `{r.object}` | {frac} | {remakes} | {1000 * r.min_finger_gap_m[pair]:.1f} ({pair})"
            f" | {1000 * r.min_gel_distance_m[near]:.1f} ({near}) | {_inside(r)} |"
        )
    return "\n".join(lines)


def _inside(report: ContactReport) -> str:
    """`finger: frames` for each finger that ended a step inside the object, or `none`."""
    listed = [f"{f}: {', '.join(map(str, v))}" for f, v in report.inside_frames.items() if v]
    return "; ".join(listed) or "none"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", nargs="*", default=list(RECIPES))
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--fps", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the reports here")
    parser.add_argument(
        "--no-render", action="store_true", help="no DIGIT renders: contact = the rig's flag"
    )
    parser.add_argument(
        "--one-axis", action="store_true", help="turn about rotation_axis only (no alternate axis)"
    )
    parser.add_argument(
        "--grasp-height", choices=GRASP_HEIGHTS, help="sensor.grasp_height (default: the config's)"
    )
    args = parser.parse_args(argv)
    motion = SimSensorConfig().rig_motion()  # the default sensor=sim motion
    if args.one_axis:
        motion["alternate_axis"] = None
    if args.grasp_height:
        motion["grasp_height"] = args.grasp_height
    try:
        objects = [_object(name) for name in args.objects]
    except (ValueError, ConfigError) as error:
        parser.error(str(error))  # one line and exit code 2, before any rig runs
    reports = []
    for obj in objects:
        report = measure(
            obj, args.duration, args.fps, args.seed, render=not args.no_render, rig_options=motion
        )
        print(json.dumps(asdict(report)), flush=True)
        reports.append(report)
    print(table(reports))
    if args.json:
        with open(args.json, "w") as f:
            json.dump([asdict(r) for r in reports], f, indent=2)


if __name__ == "__main__":
    main()
