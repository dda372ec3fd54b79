"""The classifier's forward on a GPU replayed from CUDA graphs, one launch per batch.

EfficientNet-B0's forward is a few hundred small kernels, each launched from Python. On an
H100 (a default run's profile, issue 22) a call cost 68 ms of CPU, more than the same
forward on that machine's CPU (37 ms), and the frame producer spent about half its time
there. A CUDA graph records the launches once and replays them with one call. Batches are
padded up to the next of BUCKETS, so a handful of graphs serve every batch size: in
inference, with the batch norms folded (model.fold_batch_norms), a sample's output does
not depend on the others in its batch.
"""

from __future__ import annotations

import logging

import torch
from torch import Tensor, nn

log = logging.getLogger(__name__)

BUCKETS = (1, 2, 4, 8, 16, 32, 64)  # predict_probs sends at most 64 crops per call
WARMUP_CALLS = 3  # eager calls on a side stream before a capture, as torch.cuda.graph asks


def bucket(batch: int) -> int | None:
    """The smallest bucket that holds `batch` samples; None above the largest."""
    if batch < 1:
        raise ValueError(f"batch of {batch} samples: need at least one")
    return next((b for b in BUCKETS if b >= batch), None)


class GraphedModel:
    """`model(x)` for an inference-only model: CUDA inputs through one captured graph per
    bucket, captured on first use; CPU inputs, batches above the largest bucket and any
    model whose capture failed (logged once) run the model as it is."""

    training = False  # predict_probs puts a model in eval mode only when it is training

    def __init__(self, model: nn.Module) -> None:
        if model.training:
            raise ValueError("GraphedModel replays inference only: put the model in eval mode")
        self.model = model
        self._graphs: dict[int, tuple[torch.cuda.CUDAGraph, Tensor, Tensor]] = {}
        self._pool = None  # one memory pool for every bucket's graph (replays never overlap)
        self._eager = False

    def __call__(self, x: Tensor) -> Tensor:
        size = bucket(x.shape[0])
        if x.device.type != "cuda" or self._eager or size is None:
            return self.model(x)
        entry = self._graphs.get(size) or self._capture(size, x)
        if entry is None:
            return self.model(x)
        graph, static_in, static_out = entry
        static_in[: x.shape[0]].copy_(x)
        graph.replay()
        return static_out[: x.shape[0]].clone()  # the next replay overwrites static_out

    def _capture(self, size: int, like: Tensor) -> tuple | None:
        static_in = torch.zeros((size, *like.shape[1:]), dtype=like.dtype, device=like.device)
        try:
            if self._pool is None:
                self._pool = torch.cuda.graph_pool_handle()
            side = torch.cuda.Stream(like.device)
            side.wait_stream(torch.cuda.current_stream(like.device))
            with torch.cuda.stream(side):
                for _ in range(WARMUP_CALLS):
                    self.model(static_in)
            torch.cuda.current_stream(like.device).wait_stream(side)
            graph = torch.cuda.CUDAGraph()
            # thread_local: the mapper's thread may use the GPU while this one captures.
            with torch.cuda.graph(graph, pool=self._pool, capture_error_mode="thread_local"):
                static_out = self.model(static_in)
        except RuntimeError as exc:
            log.warning("classifier: CUDA graph capture failed (%s); running it eagerly", exc)
            self._eager = True
            return None
        self._graphs[size] = (graph, static_in, static_out)
        return self._graphs[size]
