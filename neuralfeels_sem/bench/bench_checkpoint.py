"""Checkpoint size and save / load time at the CPU default config (2^16 hash table).

The field is built as a map run builds it (mapping/field_init.build_field, so untouched
rows are drawn again on load) and trained by the default mapper (MapperConfig defaults)
on the analytic sphere scene; the checkpoint is written as a run writes it (`auto`
storage: mapping/checkpoint_codec.py) and beside it, for the ratio, in `exact` storage
and whole (the format before the rows were packed). Size depends on the share of table
rows training updated, reported with it; a default run updates most of them (longer runs
more, so their checkpoints are larger).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import torch

from neuralfeels_sem.fields.optim import FieldAdam
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.mapping.checkpoint_codec import PACKED_KEY
from neuralfeels_sem.mapping.field_init import build_field
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.sphere_scene import sphere_frames
from neuralfeels_sem.perception.tactile_depth import TactileDepthConfig

FRAMES = 24  # 50 warm-up steps + 5 per frame: 165 optimiser steps


def trained_mapper(frames: int = FRAMES) -> OnlineMapper:
    torch.manual_seed(0)
    field = build_field(SemanticFieldConfig(num_classes=4), bound=0.1)
    # The sphere frames carry exact masks and depths (no images to segment or infer from).
    given = {"camera_mask": "gt", "tactile_depth": TactileDepthConfig(source="gt")}
    mapper = OnlineMapper(MapperConfig(num_classes=4, **given), field, FieldAdam, "cpu")
    for frame, labels in sphere_frames(frames, touches_per_frame=4):
        mapper.add_frame(frame, labels)
    return mapper


def _timed_save(path: Path, mapper: OnlineMapper, storage: str) -> float:
    start = time.perf_counter()
    save_checkpoint(path, mapper, frame_index=FRAMES - 1, storage=storage)
    return time.perf_counter() - start


def run() -> dict:
    mapper = trained_mapper()
    moments = mapper.optimizer.state_dict()["state"][0]["moments"]
    updated = float((moments != 0).reshape(len(moments), -1).any(dim=1).float().mean())
    with tempfile.TemporaryDirectory() as tmp:
        path, exact, whole = Path(tmp) / "auto.pt", Path(tmp) / "exact.pt", Path(tmp) / "whole.pt"
        save_s = _timed_save(path, mapper, "auto")
        exact_save_s = _timed_save(exact, mapper, "exact")
        start = time.perf_counter()
        torch.save(mapper.state_dict(), whole)
        unpacked_save_s = time.perf_counter() - start
        storage = torch.load(path, weights_only=True)["mapper"][PACKED_KEY]["encoding.table"]
        start = time.perf_counter()
        load_checkpoint(path, mapper)
        load_s = time.perf_counter() - start
        sizes = {
            name: p.stat().st_size / 1e6
            for name, p in (("auto", path), ("exact", exact), ("whole", whole))
        }
    return {
        "storage": storage["storage"],
        "size_mb": round(sizes["auto"], 1),
        "exact_size_mb": round(sizes["exact"], 1),
        "unpacked_size_mb": round(sizes["whole"], 1),
        "size_ratio_to_unpacked": round(sizes["auto"] / sizes["whole"], 3),
        "updated_row_fraction": round(updated, 3),
        "save_s": round(save_s, 2),
        "exact_save_s": round(exact_save_s, 2),
        "unpacked_save_s": round(unpacked_save_s, 2),
        "load_s": round(load_s, 2),
        "optimizer_steps": int(mapper.trained_on["optimizer_steps"]),
    }


if __name__ == "__main__":
    print(run())
