"""Which materials the rig's fingers touch, scripted gait against the active policy (rig only).

The rig runs the default sensor=sim motion for the default run length with no
rendering and no map. With `active`, each new contact is ranked by a TouchAdvice built
from the rig's own touches so far (novelty only: without a map every point counts fully
uncertain), which is what the active policy does before the map has learnt anything.
Coverage is the share of an object's materials under a touching finger's contact point in
at least `min_frames` finger-frames.

    python -m neuralfeels_sem.bench.touch_coverage --seeds 0-59 --out coverage.json
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.random_object import development_seeds, make_random_object
from neuralfeels_sem.sim.rig import SimRig
from neuralfeels_sem.sim.touch_advice import TouchAdvice, TouchScoreConfig
from neuralfeels_sem.sim.touch_planner import TouchPlanner

CLASSES = tuple(DEFAULT_MATERIALS)
POLICIES = ("scripted", "active")


def touched_materials(
    obj, policy: str = "scripted", seed: int = 0, frames: int | None = None
) -> tuple[Counter, SimRig]:
    """Finger-frames per material ("ignore": unlabelled faces) over the first `frames` frames
    (None: the default run length), and the rig."""
    if policy not in POLICIES:
        raise ValueError(f"policy={policy!r}: use {' or '.join(POLICIES)}")
    config = SimSensorConfig()
    planner = TouchPlanner() if policy == "active" else None
    rig = SimRig(obj, seed=seed, planner=planner, **config.rig_motion())
    touched: Counter[str] = Counter()
    history: list[np.ndarray] = []
    if frames is None:
        frames = round(config.duration_s * config.fps)
    for i in range(frames):
        if planner is not None:
            planner.advice = TouchAdvice(
                np.zeros((0, 3)), np.zeros(0), np.array(history).reshape(-1, 3),
                TouchScoreConfig(), i - 1,
            )  # fmt: skip
        state = rig.state_at(i / config.fps)
        points = [p for f, p in state.contact_point.items() if state.touching[f] and p is not None]
        if points:
            history.extend(points)
            labels = obj.labels_at(np.asarray(points))
            touched.update(obj.class_names[k] if k >= 0 else "ignore" for k in labels)
    return touched, rig


def coverage(touched: Counter, materials: list[str], min_frames: int) -> float:
    """Share of `materials` touched in at least `min_frames` finger-frames."""
    return sum(touched[m] >= min_frames for m in materials) / len(materials)


def run(seeds: list[int], min_frames: int = 1, frames: int | None = None) -> dict:
    """Coverage per generated object (object=random object.seed=K) and policy, over the
    first `frames` frames of each run (None: the default run length)."""
    rows = []
    for k in seeds:
        obj = make_random_object(k, CLASSES)
        materials = list(obj.generation["materials"])
        row = {"object_seed": k, "materials": materials}
        for policy in POLICIES:
            touched, _ = touched_materials(obj, policy, frames=frames)
            row[policy] = {
                "coverage": coverage(touched, materials, min_frames),
                "finger_frames": dict(touched),
            }
        rows.append(row)
        print(k, row["scripted"]["coverage"], row["active"]["coverage"], flush=True)
    mean = {p: float(np.mean([r[p]["coverage"] for r in rows])) for p in POLICIES}
    return {"min_frames": min_frames, "mean_coverage": mean, "objects": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-9", help="object seeds, e.g. 0-59 (below 1000)")
    parser.add_argument("--min-frames", type=int, default=1)
    parser.add_argument("--frames", type=int, default=None, help="default: the run length")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    try:
        seeds = development_seeds(args.seeds)
    except ValueError as exc:
        parser.error(str(exc))
    if args.frames is not None and args.frames < 1:
        parser.error(f"--frames={args.frames} must be >= 1")
    result = run(seeds, args.min_frames, args.frames)
    text = json.dumps(result, indent=1)
    if args.out is not None:
        args.out.write_text(text)
    print(json.dumps(result["mean_coverage"]))


if __name__ == "__main__":
    main()
