"""One training run of the tactile depth network: fit, save tactile_depth.pt, score it on
the held-out set, write report.json and history.json. Takes plain arrays (the task renders
them in the simulator layer)."""

from __future__ import annotations

import json
import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from neuralfeels_sem.perception.tactile_depth_net.checkpoint import save_checkpoint
from neuralfeels_sem.perception.tactile_depth_net.evaluate import score
from neuralfeels_sem.perception.tactile_depth_net.fit import FitSettings, fit
from neuralfeels_sem.perception.tactile_depth_net.predict import DepthNetPredictor

log = logging.getLogger(__name__)
CHECKPOINT_NAME = "tactile_depth.pt"


@dataclass
class DepthSet:
    """Rendered presses as plain arrays and the backgrounds to compose them over."""

    change: np.ndarray  # (N, 320, 240, 3) grey levels over the background
    press_mm: np.ndarray  # (N, 320, 240) press into the gel, 0 off-contact
    fingers: list[str]
    backgrounds: np.ndarray  # (K, 320, 240, 3) uint8
    background_names: list[str]


def train_tactile_depth(
    train: DepthSet,
    held_out: DepthSet,
    settings: FitSettings,
    out_dir: Path,
    min_contact_px: int,
    export_fp16: bool = False,
    provenance: dict | None = None,
) -> dict:
    """Train, save `out_dir/tactile_depth.pt`, score on `held_out`; returns the report."""
    start = time.perf_counter()
    model, history = fit(train.change, train.press_mm, train.backgrounds, settings)
    train_s = time.perf_counter() - start
    report = {
        "train_samples": len(train.change),
        "held_out_samples": len(held_out.change),
        "train_contact_share": round(float((train.press_mm > 0).any(axis=(1, 2)).mean()), 3),
        "held_out_contact_share": round(float((held_out.press_mm > 0).any(axis=(1, 2)).mean()), 3),
        "train_backgrounds": train.background_names,
        "held_out_backgrounds": held_out.background_names,
        "train_wall_s": round(train_s, 1),
        "settings": {**asdict(settings), "min_contact_px": int(min_contact_px)},
        **(provenance or {}),
    }
    path = save_checkpoint(
        out_dir / CHECKPOINT_NAME, model, settings.input_size, meta=report, fp16=export_fp16
    )
    predictor = DepthNetPredictor(path, min_contact_px)
    report["held_out"] = score(
        predictor,
        held_out.change,
        held_out.press_mm,
        held_out.fingers,
        held_out.backgrounds,
        settings.augmentation,
        settings.seed + 1,
    )
    report["checkpoint"] = str(path)
    report["checkpoint_fp16"] = bool(export_fp16)
    (out_dir / "report.json").write_text(json.dumps(report, indent=2))
    (out_dir / "history.json").write_text(json.dumps(history, indent=2))
    log.info("tactile depth held-out: %s", report["held_out"]["overall"])
    return report
