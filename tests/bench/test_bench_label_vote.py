"""The label vote's bench: its data and the figures it reports."""

from __future__ import annotations

import torch

from neuralfeels_sem.bench import bench_label_vote
from neuralfeels_sem.mapping.label_vote import press_events


def test_the_presses_are_clustered_frames_on_the_sphere() -> None:
    centroids, labels, fingers, frames = bench_label_vote.clustered_presses(301)
    assert centroids.shape == (301, 3) and labels.shape == (301,)
    assert len(fingers) == len(frames) == 301 and frames == sorted(frames)
    events = press_events(fingers, frames, gap=2)  # the vote's press chaining, as a run's
    frames_per_press = torch.unique(events, return_counts=True)[1]
    assert torch.equal(frames_per_press[:-1], torch.full((100,), 3))  # 3 frames a press
    radius = centroids.norm(dim=1)
    assert ((radius > 0.04) & (radius < 0.06)).all()


def test_the_bench_reports_a_time_and_a_count_per_size() -> None:
    result = bench_label_vote.run()
    for touches in bench_label_vote.TOUCHES:
        assert result[f"vote_ms_at_{touches}"] > 0
        assert 0 < result[f"outvoted_at_{touches}"] < touches
