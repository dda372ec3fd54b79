"""The tactile depth network on the rig's own touches: what `source=net` sees in `task=map`.

Runs the rig on shipped objects exactly as `sensor=sim` does by default (same motion and
seeds, so the same DIGIT backgrounds, noise and frames), predicts every finger's contact
depth with the network and scores it against the simulator's (contact IoU, depth MAE:
perception/tactile_depth_metrics.py), overall and per finger, plus the frames where one
side sees contact and the other none.

    python -m neuralfeels_sem.bench.rig_tactile_depth --seed 0 --frames 100
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from collections.abc import Sequence

import numpy as np
from tqdm import tqdm

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.objects.procedural import RECIPES
from neuralfeels_sem.perception.tactile_depth_metrics import DepthCounts, depth_counts, summarise
from neuralfeels_sem.perception.tactile_depth_net import DepthNetPredictor
from neuralfeels_sem.sim.backgrounds import finger_seed
from neuralfeels_sem.sim.rig import SimRig


def score_rig(
    objects: Sequence[str],
    seed: int = 0,
    frames: int = 100,
    fps: float = 10.0,
    checkpoint: str | None = None,
) -> dict:
    """Figures over every finger of every frame of every object."""
    from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

    predictor = DepthNetPredictor(checkpoint)
    totals: dict[str, DepthCounts] = defaultdict(DepthCounts)
    frames_by_kind: dict[str, int] = defaultdict(int)
    motion = SimSensorConfig().rig_motion()  # the default sensor=sim motion
    progress = tqdm(total=len(objects) * frames, desc="rig depth", unit="frame")
    for name in objects:
        obj = make_object(name, tuple(DEFAULT_MATERIALS))
        rig = SimRig(obj, seed=seed, **motion)
        rig.open()
        renderers = {f: DigitRenderer(obj, seed=finger_seed(seed, f)) for f in FINGERS}
        backgrounds = np.stack([r.background_image for r in renderers.values()])
        try:
            for i in range(frames):
                state = rig.state_at(i / fps)
                renders = [
                    r.render(state.world_T_object, state.world_T_sensor[f])
                    for f, r in renderers.items()
                ]
                predicted = predictor.predict(np.stack([r.image for r in renders]), backgrounds)
                for finger, render, depth in zip(FINGERS, renders, predicted, strict=True):
                    totals[finger] += depth_counts(depth, render.depth, render.contact_mask)
                    kind = (bool(render.contact_mask.any()), bool(depth.any()))
                    frames_by_kind[_KINDS[kind]] += 1
                progress.update(1)
        finally:
            for renderer in renderers.values():
                renderer.close()
    progress.close()
    return {
        "objects": list(objects),
        "seed": seed,
        "frames_per_object": frames,
        "overall": summarise(sum(totals.values(), DepthCounts())),
        "per_finger": {f: summarise(c) for f, c in totals.items()},
        "finger_frames": dict(frames_by_kind),
    }


_KINDS = {
    (True, True): "both_contact",
    (True, False): "missed_contact",
    (False, True): "false_contact",
    (False, False): "both_none",
}


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+", default=sorted(RECIPES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=100, help="frames per object (10 fps)")
    parser.add_argument("--checkpoint", default=None, help="tactile_depth.pt (default: shipped)")
    args = parser.parse_args(argv)
    print(
        json.dumps(
            score_rig(args.objects, args.seed, args.frames, checkpoint=args.checkpoint), indent=1
        )
    )


if __name__ == "__main__":
    main()
