"""Cost of one evaluation on a shipped object: matching % (3D and image form), shape metrics, plots.

The predictor is a nearest-face lookup on the ground truth (a stand-in for the field, whose
own cost is measured by the field benchmarks), so the figures are the evaluation's overhead.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from neuralfeels_sem.configs.eval import EvalConfig
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.eval.image_matching import ImageMatcher
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.shape import shape_metrics
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.viz.plots import plot_matching_curve, plot_material_maps

CLASSES = tuple(DEFAULT_MATERIALS)


def _timed(fn, repeats: int = 1) -> tuple[float, object]:
    start = time.perf_counter()
    for _ in range(repeats):
        result = fn()
    return (time.perf_counter() - start) / repeats, result


def run() -> dict:
    cfg = EvalConfig()
    obj = make_object("patched_toy", CLASSES)
    rng = np.random.default_rng(0)

    def predict(points: np.ndarray) -> np.ndarray:  # cost of a trivial predictor, ~0
        return (points[:, 0] > 0).astype(np.int64) * 2

    init_s, evaluator = _timed(lambda: MatchingEvaluator(obj, cfg.num_surface_samples, cfg.seed))
    score_s, _ = _timed(lambda: evaluator.score(predict), repeats=10)

    matcher = ImageMatcher(obj, cfg.image_views, cfg.image_size, cfg.image_elevation_deg, cfg.seed)
    prepare_s, maps = _timed(lambda: matcher.maps(predict))
    maps_s, maps = _timed(lambda: matcher.maps(predict), repeats=5)

    pred_mesh = obj.mesh.copy()
    pred_mesh.vertices = pred_mesh.vertices + rng.normal(0, 1e-3, pred_mesh.vertices.shape)
    shape_s, shape = _timed(
        lambda: shape_metrics(
            pred_mesh, obj.mesh, cfg.shape_samples, cfg.fscore_thresholds_mm, cfg.seed
        )
    )

    with tempfile.TemporaryDirectory() as tmp:
        curve = [[i * 5, i * 0.5, 40.0 + i] for i in range(40)]
        curve_plot_s, _ = _timed(lambda: plot_matching_curve(curve, Path(tmp) / "c.png"))
        maps_plot_s, _ = _timed(lambda: plot_material_maps(maps, CLASSES, Path(tmp) / "m.png"))

    return {
        "object": obj.name,
        "object_faces": int(len(obj.mesh.faces)),
        "surface_samples": cfg.num_surface_samples,
        "matching_init_s": round(init_s, 4),
        "matching_score_s": round(score_s, 5),
        "image_views": cfg.image_views,
        "image_size": cfg.image_size,
        "image_pixels_scored": int(len(matcher.points)),
        "image_first_call_s": round(prepare_s, 3),
        "image_maps_s": round(maps_s, 4),
        "shape_samples": cfg.shape_samples,
        "shape_metrics_s": round(shape_s, 3),
        "shape_chamfer_mm_1mm_noise": round(shape["chamfer_mm"], 3),
        "plot_matching_curve_s": round(curve_plot_s, 3),
        "plot_material_maps_s": round(maps_plot_s, 3),
    }
