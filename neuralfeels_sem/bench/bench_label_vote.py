"""The label vote's cost per frame at a run's touch counts.

The mapper reruns the vote (mapping/label_vote.py) over every touch so far whenever new
touches arrive, so its cost per frame grows with the run's length: a default run of 30 s
holds about 1000 touch readings, a 100 s run about 3000. Data: presses of three frames
each by the four fingers in turn, at random places on a 5 cm sphere (the frames of a press
within 2 mm), four materials, half the presses naming one material in all three frames
(steady), the others one per frame; the vote at the command line's settings
(MapperConfig), called as TouchBuffer calls it (LabelVote.outvoted: presses, steadiness,
neighbours and support).
"""

from __future__ import annotations

import time

import torch

from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.mapping.label_vote import LabelVote
from neuralfeels_sem.mapping.mapper import MapperConfig

TOUCHES = (1000, 3000)
REPEATS = 5
FRAMES_PER_PRESS = 3
FRAMES_BETWEEN_PRESSES = 10  # a finger's presses lie 40 frames apart: never one press


def clustered_presses(touches: int, seed: int = 0) -> tuple:
    """(centroids (T, 3), labels (T,), fingers, frames) of `touches` readings in frame
    order, press p by finger p mod 4 from frame FRAMES_BETWEEN_PRESSES * p on."""
    gen = torch.Generator().manual_seed(seed)
    presses = -(-touches // FRAMES_PER_PRESS)
    directions = torch.nn.functional.normalize(torch.randn(presses, 3, generator=gen), dim=1)
    press = torch.arange(presses).repeat_interleave(FRAMES_PER_PRESS)[:touches]
    centroids = 0.05 * directions[press] + 0.002 * torch.randn(touches, 3, generator=gen)
    steady = torch.rand(presses, generator=gen) < 0.5
    labels = torch.where(
        steady[press],
        torch.randint(0, 4, (presses,), generator=gen)[press],
        torch.randint(0, 4, (touches,), generator=gen),
    )
    frame_in_press = torch.arange(touches) % FRAMES_PER_PRESS
    frames = (press * FRAMES_BETWEEN_PRESSES + frame_in_press).tolist()
    fingers = [FINGERS[p % len(FINGERS)] for p in press.tolist()]
    return centroids, labels, fingers, frames


def run() -> dict:
    vote = LabelVote.from_config(MapperConfig())
    result = {}
    for touches in TOUCHES:
        readings = clustered_presses(touches)
        start = time.perf_counter()
        for _ in range(REPEATS):
            outvoted = vote.outvoted(*readings)
        result[f"vote_ms_at_{touches}"] = round(1000 * (time.perf_counter() - start) / REPEATS, 2)
        result[f"outvoted_at_{touches}"] = int(outvoted.sum())
    return result
