"""A network's inference forward on a GPU replayed from CUDA graphs, one launch per batch.

EfficientNet-B0's forward (the material classifier) is a few hundred small kernels, each
launched from Python. On an H100 (a default run's profile, issue 22) a call cost 68 ms of
CPU, more than the same forward on that machine's CPU (37 ms), and the frame producer spent
about half its time there. The tactile depth network's forward and its bilinear
upsampling (a decomposition run op by op in Python) are launched the same way: replayed
from graphs, the producer's perceive stage took 22 ms of CPU a frame instead of 32 (the
2^24 default run on an H200). A CUDA graph records the launches once and replays them with
one call. Batches are padded up
to the next bucket, so a handful of graphs serve every batch size: in inference, with batch
norms in eval mode (or folded), a sample's output does not depend on the others in its
batch.
"""

from __future__ import annotations

import logging

import torch
from torch import Tensor, nn

log = logging.getLogger(__name__)

BUCKETS = (1, 2, 4, 8, 16, 32, 64)  # predict_probs sends at most 64 crops per call
WARMUP_CALLS = 3  # eager calls on a side stream before a capture, as torch.cuda.graph asks
Output = Tensor | tuple[Tensor, ...]


def bucket(batch: int, buckets: tuple[int, ...] = BUCKETS) -> int | None:
    """The smallest of `buckets` that holds `batch` samples; None above the largest."""
    if batch < 1:
        raise ValueError(f"batch of {batch} samples: need at least one")
    return next((b for b in buckets if b >= batch), None)


class GraphedModel:
    """`model(x)` for an inference-only model whose output is a tensor or a tuple of
    tensors, each with the batch first: CUDA inputs through one captured graph per bucket,
    captured on first use or ahead by `capture`; CPU inputs, batches above the largest
    bucket and any model whose capture failed (logged once) run the model as it is."""

    training = False  # predict_probs puts a model in eval mode only when it is training

    def __init__(self, model: nn.Module, buckets: tuple[int, ...] = BUCKETS) -> None:
        if model.training:
            raise ValueError("GraphedModel replays inference only: put the model in eval mode")
        self.model = model
        self.buckets = buckets
        # one graph per (bucket, sample shape, dtype): a graph replays one input shape only
        self._graphs: dict[tuple, tuple[torch.cuda.CUDAGraph, Tensor, Output]] = {}
        self._pool = None  # one memory pool for every bucket's graph (replays never overlap)
        self._eager = False

    def __call__(self, x: Tensor) -> Output:
        size = bucket(x.shape[0], self.buckets)
        if x.device.type != "cuda" or self._eager or size is None:
            return self.model(x)
        entry = self._graphs.get(_key(size, x)) or self._capture(size, x)
        if entry is None:
            return self.model(x)
        graph, static_in, static_out = entry
        n = x.shape[0]
        with torch.inference_mode():  # the graphs' buffers are inference tensors
            static_in[:n].copy_(x)
            graph.replay()
            # the next replay overwrites static_out: hand out copies
            if isinstance(static_out, tuple):
                return tuple(out[:n].clone() for out in static_out)
            return static_out[:n].clone()

    @torch.inference_mode()
    def capture(self, sample_shape: tuple[int, ...], device: torch.device) -> None:
        """Capture every bucket's graph now, for float32 samples of `sample_shape`.

        A bucket's first capture costs far more than its replays (the first calls of each
        convolution shape): in a default run on an H200 that captured them on first use, the
        first frame, which also loaded the networks, took 13-17 s. A run captures them
        before its clock starts.
        """
        like = torch.zeros((1, *sample_shape), device=device)
        for size in self.buckets:
            if self._eager:
                return
            if _key(size, like) not in self._graphs:
                self._capture(size, like)

    def captured(self) -> list[tuple[int, tuple[int, ...]]]:
        """(bucket, sample shape) of every graph captured so far, sorted."""
        return sorted((size, shape) for size, shape, _ in self._graphs)

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
            name = type(self.model).__name__
            log.warning("%s: CUDA graph capture failed (%s); running it eagerly", name, exc)
            self._eager = True
            return None
        entry = self._graphs[_key(size, like)] = (graph, static_in, static_out)
        return entry


def _key(size: int, x: Tensor) -> tuple:
    return size, tuple(x.shape[1:]), x.dtype
