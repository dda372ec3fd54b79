"""Semantic field training speed and memory: steps/s at 4096 points per step.

One step = SemanticField forward (SDF + material branch) on 4096 points, an L1 SDF loss
plus a cross-entropy material loss, backward, FieldAdam step. Measured for the CPU default
table (HashGridConfig.log2_table_size, 16), a larger one (19: table and moments no longer
fit a 32 MB cache) and the paper's (24), with row-sparse and dense table gradients. Each configuration runs in a fresh process so its peak RSS (max resident set
size minus the size after imports, during training; `..._with_query` also covers one
65536-point no-grad SDF query, the marching-cubes chunk) is its own. On a CUDA machine the GPU rows are added,
with torch's peak allocated memory.
"""

from __future__ import annotations

import multiprocessing as mp
import resource
import time

import torch
import torch.nn.functional as F

from neuralfeels_sem.fields.hash_grid import HashGridConfig
from neuralfeels_sem.utils.device import resolve_threads

POINTS = 4096
NUM_CLASSES = 4
WARMUP_STEPS = 2
MIN_STEPS, MAX_STEPS, TIME_BUDGET_S = 3, 30, 6.0


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _train_step(field, opt, g: torch.Generator, device: str) -> None:
    """One step on 4096 random points: L1 loss to a 5 cm sphere's SDF plus material CE."""
    x = (torch.rand(POINTS, 3, generator=g, device=device) * 2 - 1) * 0.1
    labels = torch.randint(0, NUM_CLASSES, (POINTS,), generator=g, device=device)
    out = field(x)
    loss = (out["sdf"] - (x.norm(dim=-1) - 0.05)).abs().mean() + F.cross_entropy(
        out["material_logits"], labels
    )
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()


def _time_steps(field, opt, g: torch.Generator, device: str) -> tuple[int, float, float]:
    """Warm up, then step for TIME_BUDGET_S (MIN_STEPS..MAX_STEPS): steps, wall s, CPU s."""
    for _ in range(WARMUP_STEPS):
        _train_step(field, opt, g, device)
    _sync(device)
    if device.startswith("cuda"):
        torch.cuda.reset_peak_memory_stats()
    steps, start, cpu_start = 0, time.perf_counter(), time.process_time()
    while steps < MAX_STEPS and (steps < MIN_STEPS or time.perf_counter() - start < TIME_BUDGET_S):
        _train_step(field, opt, g, device)
        _sync(device)
        steps += 1
    return steps, time.perf_counter() - start, time.process_time() - cpu_start


def _query_seconds(field, device: str) -> float:
    """Dense query time (marching cubes path): SDF only, no grad, one 65536-point chunk."""
    q = (torch.rand(65536, 3, device=device) * 2 - 1) * 0.1
    with torch.no_grad():
        field.sdf(q)
        _sync(device)
        t0 = time.perf_counter()
        for _ in range(3):
            field.sdf(q)
        _sync(device)
        return (time.perf_counter() - t0) / 3


def _measure(log2_table_size: int, sparse: bool, device: str) -> dict:
    from neuralfeels_sem.fields import FieldAdam, SemanticField
    from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig

    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    torch.manual_seed(0)
    encoding = HashGridConfig(log2_table_size=log2_table_size, sparse_grad=sparse)
    config = SemanticFieldConfig(num_classes=NUM_CLASSES, encoding=encoding)
    field = SemanticField(config, bound=0.1).to(device)
    opt = FieldAdam(field.parameters(), lr=1e-3)
    g = torch.Generator(device=device).manual_seed(0)
    steps, elapsed, cpu = _time_steps(field, opt, g, device)
    # ru_maxrss is in KiB on Linux; read it before the large query below.
    train_rss_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024
    query_s = _query_seconds(field, device)

    result = {
        "steps_per_s": round(steps / elapsed, 3),
        "ms_per_step": round(1000 * elapsed / steps, 1),
        # CPU seconds of this process (all threads) per step: a load-independent figure
        # when the cores are shared (wall time then mostly measures the other processes).
        "cpu_ms_per_step": round(1000 * cpu / steps, 1),
        "steps_timed": steps,
        "table_rows": int(field.encoding.table.shape[0]),
        "params_mb": round(
            sum(p.numel() * p.element_size() for p in field.parameters()) / 2**20, 1
        ),
        "sdf_query_points_per_s": round(65536 / query_s),
    }
    if device.startswith("cuda"):
        result["peak_gpu_mb"] = round(torch.cuda.max_memory_allocated() / 2**20, 1)
    else:
        result["peak_rss_delta_mb"] = round(train_rss_mb, 1)
        query_rss_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024
        result["peak_rss_delta_mb_with_query"] = round(query_rss_mb, 1)
    return result


def _child(queue, log2: int, sparse: bool, device: str, threads: int) -> None:
    torch.set_num_threads(threads)
    try:
        queue.put(_measure(log2, sparse, device))
    except Exception as exc:  # an out-of-memory or similar: report it, keep the others
        queue.put({"error": f"{type(exc).__name__}: {exc}"})


def _run_isolated(log2: int, sparse: bool, device: str) -> dict:
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    # The thread count a run's `threads=auto` picks (utils/device.py).
    threads = resolve_threads("auto")
    proc = ctx.Process(target=_child, args=(queue, log2, sparse, device, threads))
    proc.start()
    try:
        result = queue.get(timeout=300)
    except Exception:
        result = {"error": f"no result (exit code {proc.exitcode}; out of memory?)"}
    proc.join(timeout=30)
    return result


# (log2 table size, name in the report's keys)
TABLES = ((HashGridConfig().log2_table_size, "cpu_default"), (19, "larger"), (24, "paper"))


def run() -> dict:
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    results: dict = {"points_per_step": POINTS, "threads": resolve_threads("auto")}
    for device in devices:
        for log2, name in TABLES:
            for sparse in (True, False):
                key = f"{device}_{name}_log2_{log2}_{'sparse' if sparse else 'dense'}"
                print(f"[bench_field] {key} ...", flush=True)
                results[key] = _run_isolated(log2, sparse, device)
    return results


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
