"""Scoring off the mapper's path: a copy of the field, in order, errors raised on the mapper's side."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from neuralfeels_sem.pipeline.background_eval import BackgroundEval


class _Scorer:
    def __init__(self, fail_at: int | None = None) -> None:
        self.curve: list[list[float]] = []
        self.fail_at = fail_at

    def score(self, field, frame_index, time_s, field_T_gt):
        if frame_index == self.fail_at:
            raise RuntimeError(f"scoring failed at {frame_index}")
        value = float(field.weight.detach().sum())
        self.curve.append([frame_index, time_s, value])
        return {"matching_mean_class_pct": value}


def _field(value: float) -> nn.Linear:
    field = nn.Linear(2, 1, bias=False)
    with torch.no_grad():
        field.weight.fill_(value)
    return field


def test_jobs_score_a_copy_in_order_and_write_snapshots() -> None:
    scorer, snapshots = _Scorer(), []
    background = BackgroundEval(
        scorer, lambda f, T, t, i: snapshots.append((i, float(f.weight.detach().sum())))
    )
    field = _field(1.0)
    for index in range(4):
        background.submit(field, index, index * 0.1, None, score=True, snapshot=index % 2 == 0)
        with torch.no_grad():
            field.weight.add_(1.0)  # the mapper trains on: the job keeps the field it was given
    passes = background.drain()
    background.close()
    assert [p[0] for p in passes] == [0, 1, 2, 3]
    assert [row[2] for row in scorer.curve] == [2.0, 4.0, 6.0, 8.0]
    assert snapshots == [(0, 2.0), (2, 6.0)]


def test_an_error_in_the_worker_is_raised_on_the_mappers_side() -> None:
    background = BackgroundEval(_Scorer(fail_at=1), lambda *a: None)
    field = _field(0.0)
    background.submit(field, 0, 0.0, None, score=True, snapshot=False)
    background.submit(field, 1, 0.1, None, score=True, snapshot=False)
    with pytest.raises(RuntimeError, match="scoring failed at 1"):
        background.drain()
    background.close()
