"""Everything a mapping run is scored on, in one object the task loop calls.

Usage in task=map (the predictor maps (N, 3) object-frame points to (N,) class indices):

    ev = RunEvaluator(obj, every_k_frames=5, expected_frames=len(frames))
    base = ev.baseline(predict, mesh=None)                      # before any training
    for frame in frames:
        for finger, touch in touches.items(): ev.touch(finger, touch.label, gt_material_of(reading))
        ...train...
        if ev.is_due(frame.index, last=...): ev.step(frame.index, frame.time_s, predict)
    metrics = ev.final(predict, extracted_mesh)                  # metrics.json entries
    ev.write_pictures(out_dir, predict, extracted_mesh)          # pngs + material_mesh.ply
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import trimesh

from neuralfeels_sem.eval.classifier_metrics import ClassifierAccuracy
from neuralfeels_sem.eval.image_matching import ImageMatcher
from neuralfeels_sem.eval.matching import MatchingEvaluator, Predictor
from neuralfeels_sem.eval.shape import shape_metrics
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.viz.material_mesh import save_material_mesh
from neuralfeels_sem.viz.plots import (
    plot_fscore_curve,
    plot_matching_curve,
    plot_material_maps,
    plot_progression,
)


class RunEvaluator:
    """Matching curve, progression snapshots, classifier tallies and final metrics of one run."""

    def __init__(
        self,
        obj: MaterialObject,
        every_k_frames: int = 5,
        num_surface_samples: int = 20000,
        image_views: int = 4,
        image_size: int = 256,
        image_elevation_deg: float = 30.0,
        fscore_thresholds_mm: Sequence[float] = tuple(range(1, 21)),
        shape_samples: int = 20000,
        seed: int = 0,
        progression_snapshots: int = 5,
        expected_frames: int | None = None,
        progression_view: int = 0,
    ) -> None:
        if every_k_frames < 1 or progression_snapshots < 1:
            raise ValueError("every_k_frames and progression_snapshots must be >= 1")
        if not 0 <= progression_view < image_views:
            raise ValueError(f"progression_view={progression_view} must be in 0..{image_views - 1}")
        self.obj = obj
        self.class_names = tuple(obj.class_names)
        self.every_k_frames = every_k_frames
        self.num_surface_samples = num_surface_samples
        self.thresholds_mm = [float(t) for t in fscore_thresholds_mm]
        self.shape_samples = shape_samples
        self.seed = seed
        self.progression_view = progression_view
        self.image = ImageMatcher(obj, image_views, image_size, image_elevation_deg, seed)
        self.classifier = ClassifierAccuracy()
        self.curve: list[list[float]] = []
        self.snapshots: list[tuple[float, dict]] = []
        # Frames at which the progression keeps a map: evenly spread over the expected run, or
        # at doubling frame indices when its length is unknown (few renders either way); the
        # final map is always added by write_pictures.
        self._expected_frames = expected_frames if expected_frames and expected_frames > 1 else None
        self._targets: list[float] = (
            list(np.linspace(0, self._expected_frames - 1, progression_snapshots)[:-1])
            if self._expected_frames
            else [0.0]
        )
        self._progression_snapshots = progression_snapshots
        self._matching: MatchingEvaluator | None = None
        self._last_maps: dict | None = None

    @property
    def matching(self) -> MatchingEvaluator:
        if self._matching is None:  # sampling is cheap, but keep the constructor free of work
            self._matching = MatchingEvaluator(self.obj, self.num_surface_samples, self.seed)
        return self._matching

    def is_due(self, frame_index: int, last: bool = False) -> bool:
        return last or frame_index % self.every_k_frames == 0

    def _view(self, maps: dict) -> dict:
        """A one-view copy of label maps, for the progression figure."""
        v = self.progression_view
        return {k: maps[k][v : v + 1] for k in ("gt", "pred", "diff", "shade")} | {
            "matching_pct_image": maps["matching_pct_image"]
        }

    def step(self, frame_index: int, time_s: float, predict: Predictor) -> float:
        """Score the map now: appends [frame, time, matching %] to the curve and returns the %."""
        pct = self.matching.score(predict)
        self.curve.append([int(frame_index), float(time_s), pct])
        if self._targets and frame_index >= self._targets[0]:
            while self._targets and frame_index >= self._targets[0]:
                self._targets.pop(0)
            if self._expected_frames is None:
                self._targets.append(float(max(self.every_k_frames, 2 * frame_index)))
            self.snapshots.append((float(time_s), self._view(self.image.maps(predict))))
        return pct

    def touch(self, finger: str, predicted: int, gt: int | None) -> None:
        """One classified touch (NO_LABEL = abstained) against the simulator's ground truth."""
        self.classifier.update(finger, predicted, gt)

    def _map_metrics(self, predict: Predictor, mesh: trimesh.Trimesh | None) -> dict:
        result = self.matching.evaluate(predict)
        maps = self.image.maps(predict)
        out = {
            "matching_pct": result["matching_pct"],
            "matching_pct_per_class": result["per_class"],
            "matching_pct_image": maps["matching_pct_image"],
        }
        if mesh is not None and len(mesh.faces):
            out.update(
                shape_metrics(
                    mesh, self.obj.mesh, self.shape_samples, self.thresholds_mm, self.seed
                )
            )
        return out | {"_maps": maps}

    def baseline(self, predict: Predictor, mesh: trimesh.Trimesh | None = None) -> dict:
        """The same metrics for the untrained field (metrics.json `baseline`)."""
        out = self._map_metrics(predict, mesh)
        out.pop("_maps")
        return out

    def final(self, predict: Predictor, mesh: trimesh.Trimesh | None = None) -> dict:
        """matching_pct, matching_pct_image, per class, matching_curve, shape metrics, classifier_accuracy.

        The curve holds the scheduled steps; call step() on the last frame too (is_due(i, last=True))
        so that it ends at the final score.
        """
        out = self._map_metrics(predict, mesh)
        self._last_maps = out.pop("_maps")
        out["matching_curve"] = [list(row) for row in self.curve]
        out["classifier_accuracy"] = self.classifier.summary(self.class_names)
        return out

    def write_pictures(
        self,
        out_dir: Path | str,
        predict: Predictor,
        mesh: trimesh.Trimesh | None = None,
        baseline_pct: float | None = None,
        metrics: dict | None = None,
        dpi: int = 120,
    ) -> list[Path]:
        """matching_curve.png, material_maps.png, progression.png, fscore_curve.png, material_mesh.ply."""
        out_dir = Path(out_dir)
        maps = self._last_maps if self._last_maps is not None else self.image.maps(predict)
        final_time = self.curve[-1][1] if self.curve else 0.0
        keep = self._progression_snapshots - 1
        chosen = (
            np.unique(np.linspace(0, len(self.snapshots) - 1, keep).round().astype(int))
            if keep and self.snapshots
            else []
        )
        snapshots = [*(self.snapshots[i] for i in chosen), (final_time, self._view(maps))]
        paths = [
            plot_material_maps(maps, self.class_names, out_dir / "material_maps.png", dpi=dpi),
            plot_progression(snapshots, self.class_names, out_dir / "progression.png", dpi=dpi),
        ]
        if self.curve:
            paths.append(
                plot_matching_curve(
                    self.curve,
                    out_dir / "matching_curve.png",
                    baseline=baseline_pct,
                    title=self.obj.name,
                    dpi=dpi,
                )
            )
        if metrics and metrics.get("fscore_curve"):
            paths.append(
                plot_fscore_curve(metrics["fscore_curve"], out_dir / "fscore_curve.png", dpi=dpi)
            )
        if mesh is not None and len(mesh.faces):
            paths.append(
                save_material_mesh(mesh, predict, self.class_names, out_dir / "material_mesh.ply")
            )
        return paths
