"""GraphedModel (perception/graphed.py) off the GPU: bucket sizes, bad input, and
CPU inputs passed to the model as they are. The replay itself is checked against the eager
forward in tests/gpu/test_gpu_paths.py."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from neuralfeels_sem.perception.graphed import BUCKETS, GraphedModel, _key, bucket


def test_a_batch_goes_to_the_smallest_bucket_that_holds_it() -> None:
    assert [bucket(n) for n in (1, 2, 3, 5, 8, 9, 33, 64)] == [1, 2, 4, 8, 8, 16, 64, 64]
    assert bucket(BUCKETS[-1] + 1) is None  # run eagerly
    with pytest.raises(ValueError, match="at least one"):
        bucket(0)


def test_a_model_in_training_mode_is_refused() -> None:
    with pytest.raises(ValueError, match="eval mode"):
        GraphedModel(nn.Linear(3, 2).train())


def test_cpu_inputs_run_the_model_as_it_is() -> None:
    torch.manual_seed(0)
    model = nn.Sequential(nn.Linear(3, 4), nn.SiLU(), nn.Linear(4, 2)).eval()
    x = torch.randn(5, 3)
    graphed = GraphedModel(model)
    assert torch.equal(graphed(x), model(x))
    assert graphed.training is False


def test_capture_takes_every_bucket_once_per_sample_shape(monkeypatch) -> None:
    # The capture itself needs CUDA (tests/gpu); here its bookkeeping: one graph per
    # bucket and sample shape, none taken twice, another shape getting graphs of its own.
    graphed = GraphedModel(nn.Identity().eval(), buckets=(1, 2, 4))
    taken = []

    def fake_capture(size: int, like: torch.Tensor) -> tuple:
        taken.append((size, tuple(like.shape[1:])))
        graphed._graphs[_key(size, like)] = (None, None, None)
        return graphed._graphs[_key(size, like)]

    monkeypatch.setattr(graphed, "_capture", fake_capture)
    cpu = torch.device("cpu")
    graphed.capture((3, 8, 8), cpu)
    graphed.capture((3, 8, 8), cpu)  # already there: nothing new
    assert taken == [(1, (3, 8, 8)), (2, (3, 8, 8)), (4, (3, 8, 8))]
    graphed.capture((3, 16, 12), cpu)
    assert graphed.captured() == sorted(
        [(b, (3, 8, 8)) for b in (1, 2, 4)] + [(b, (3, 16, 12)) for b in (1, 2, 4)]
    )
    assert [bucket(n, graphed.buckets) for n in (1, 3, 4, 5)] == [1, 4, 4, None]
