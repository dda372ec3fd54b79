"""The label vote's cost per frame at a run's touch counts.

The mapper reruns the vote (mapping/label_vote.py) over every touch so far whenever new
touches arrive, so its cost per frame grows with the run's length: a default run of 30 s
holds about 1000 touch readings, a 100 s run about 3000. Data: presses of three frames
each at random places on a 5 cm sphere (the frames of a press within 2 mm), four
materials, half the presses steady; the vote at the command line's settings (MapperConfig).
"""

from __future__ import annotations

import time

import torch

from neuralfeels_sem.mapping.label_vote import LabelVote, outvoted_touches
from neuralfeels_sem.mapping.mapper import MapperConfig

TOUCHES = (1000, 3000)
REPEATS = 5
FRAMES_PER_PRESS = 3


def clustered_presses(touches: int, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """(centroids (T, 3), labels (T,), press ids (T,), steady (T,)) of `touches` readings."""
    gen = torch.Generator().manual_seed(seed)
    presses = -(-touches // FRAMES_PER_PRESS)
    directions = torch.nn.functional.normalize(torch.randn(presses, 3, generator=gen), dim=1)
    events = torch.arange(presses).repeat_interleave(FRAMES_PER_PRESS)[:touches]
    centroids = 0.05 * directions[events] + 0.002 * torch.randn(touches, 3, generator=gen)
    labels = torch.randint(0, 4, (touches,), generator=gen)
    steady = torch.rand(touches, generator=gen) < 0.5
    return centroids, labels, events, steady


def run() -> dict:
    vote = LabelVote.from_config(MapperConfig())
    result = {}
    for touches in TOUCHES:
        centroids, labels, events, steady = clustered_presses(touches)
        start = time.perf_counter()
        for _ in range(REPEATS):
            outvoted = vote_once(vote, centroids, labels, events, steady)
        result[f"vote_ms_at_{touches}"] = round(1000 * (time.perf_counter() - start) / REPEATS, 2)
        result[f"outvoted_at_{touches}"] = int(outvoted.sum())
    return result


def vote_once(
    vote: LabelVote,
    centroids: torch.Tensor,
    labels: torch.Tensor,
    events: torch.Tensor,
    steady: torch.Tensor,
) -> torch.Tensor:
    """One vote over prepared presses (what TouchBuffer asks after a frame's touches)."""
    return outvoted_touches(
        centroids,
        labels,
        vote.radius,
        vote.min_neighbours,
        vote.min_agreement,
        vote.min_support,
        events,
        vote.support_radius,
        steady,
    )
