"""Which materials the default sim motion touches: finger-frames per material, rig only."""

from __future__ import annotations

from collections import Counter

import numpy as np

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.sim.rig import SimRig

# The default motion's first stretch about each axis (it alternates every 5 s): what the
# tests' measured counts refer to, and the motion of a run of any length's first 10 s.
FIRST_SECONDS = 10.0


def touched_materials(obj, class_names: tuple[str, ...]) -> tuple[Counter, SimRig]:
    """Finger-frames per material ("ignore" for unlabelled faces) under a touching finger's
    contact point over the default motion's first FIRST_SECONDS (seed 0), and the rig that
    made them."""
    config = SimSensorConfig()
    rig = SimRig(obj, seed=0, **config.rig_motion())
    touched: Counter[str] = Counter()
    for i in range(round(min(FIRST_SECONDS, config.duration_s) * config.fps)):
        state = rig.state_at(i / config.fps)
        points = [p for f, p in state.contact_point.items() if state.touching[f] and p is not None]
        if points:
            labels = obj.labels_at(np.asarray(points))
            touched.update(class_names[k] if k >= 0 else "ignore" for k in labels)
    return touched, rig
