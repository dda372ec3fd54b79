"""Scoring of a mapping run, during and after it: what goes into metrics.json and the pictures.

`RunScorer` holds the fixed ground-truth samples, the matching curves, the touch log
(every classified touch with its ground truth) and progression snapshots. Its state is
plain data so a checkpoint can carry it and a resumed run loses none of it.

Every matching figure is read against `baseline_majority`, the constant map that paints
the whole object in the ground truth's majority material (on the true surface): on an
object that is 96 % fabric it already scores 96 % `matching_pct`, but only
100 / classes % `matching_mean_class_pct`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import transform_points
from neuralfeels_sem.eval.classifier_metrics import ClassifierAccuracy, gt_material_of, never_read
from neuralfeels_sem.eval.image_matching import ImageMatcher
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.mesh_transfer import labels_from_mesh
from neuralfeels_sem.eval.shape import shape_metrics
from neuralfeels_sem.eval.uncertainty import (
    entropy_of_probabilities,
    probability_predictor,
    uncertainty_scores,
)
from neuralfeels_sem.fields.semantic_field import evaluate_chunked
from neuralfeels_sem.mapping.mesh import extract_mesh
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.perception.touch import TouchLabel, abstention

log = logging.getLogger(__name__)

# Matching figures of a field, in metrics.json order: the headline first.
RUN_MATCHING_KEYS = (
    "matching_mean_class_pct",
    "matching_pct",
    "matching_miou_pct",
    "matching_mesh_pct",
    "matching_mesh_mean_class_pct",
    "matching_pct_image",
    "matching_per_class",
)
SHAPE_KEYS = ("fscore_5mm", "chamfer_mm", "fscore_curve")


def material_predictor(
    field: nn.Module, field_T_gt: np.ndarray | None = None, chunk: int = 65536
) -> Callable[[np.ndarray], np.ndarray]:
    """(N,3) ground-truth object-frame points -> (N,) predicted class, in chunks without gradients.

    `field_T_gt` maps ground-truth object coordinates into the field's frame (identity when
    the field was trained with ground-truth poses).
    """
    device = next(field.parameters()).device

    def predict(points: np.ndarray) -> np.ndarray:
        if field_T_gt is not None:
            points = transform_points(field_T_gt, np.asarray(points, dtype=np.float64))
        x = torch.as_tensor(np.asarray(points, dtype=np.float32), device=device)
        return evaluate_chunked(field.predict_material, x, chunk).cpu().numpy().astype(np.int64)

    return predict


class RunScorer:
    """Metrics of one mapping run against the object's ground truth."""

    def __init__(
        self,
        obj: MaterialObject,
        num_surface_samples: int,
        image_views: int,
        image_size: int,
        image_elevation_deg: float,
        fscore_thresholds_mm: Sequence[float],
        shape_samples: int,
        mesh_resolution: int,
        seed: int,
        mesh_match_tolerance_m: float = 0.005,
    ) -> None:
        self.obj = obj
        self.class_names = list(obj.class_names)
        self.notes: list[str] = []
        try:
            self.matching: MatchingEvaluator | None = MatchingEvaluator(
                obj, num_surface_samples, seed
            )
            self.images: ImageMatcher | None = ImageMatcher(
                obj, image_views, image_size, image_elevation_deg, seed
            )
        except NoDataError as exc:
            self.matching = self.images = None
            self.notes.append(f"matching skipped: {exc}")
            log.warning("matching percentage skipped: %s", exc)
        else:
            self.notes.extend(self.matching.notes)
        self.fscore_thresholds_mm = list(fscore_thresholds_mm)
        self.shape_samples = shape_samples
        self.mesh_resolution = mesh_resolution
        self.mesh_match_tolerance_m = mesh_match_tolerance_m
        self.seed = seed
        self.curve: list[list[float]] = []  # [frame_index, time_s, matching_pct]
        self.mean_class_curve: list[list[float]] = []  # [frame_index, time_s, mean-class %]
        self._majority: dict | None = None  # majority_baseline(), once computed
        # [frame_index, finger, predicted, gt or -1, confidence, top class or -1, abstained]
        self.touch_log: list[list] = []

    # ---------------------------------------------------------------- during the run
    def log_touches(self, frame: Frame, labels: dict[str, TouchLabel]) -> None:
        for finger, label in labels.items():
            if not label.contact:
                continue
            gt = gt_material_of(frame.tactile[finger])
            self.touch_log.append(
                [
                    frame.index,
                    finger,
                    int(label.label),
                    -1 if gt is None else gt,
                    float(label.confidence),
                    -1 if label.probs is None else int(np.argmax(label.probs)),
                    abstention(label),
                ]
            )

    def score(
        self,
        field: nn.Module,
        frame_index: int,
        time_s: float,
        field_T_gt: np.ndarray | None = None,
    ) -> dict | None:
        """Matching figures of the field now (keys as `label_scores`), added to the curves."""
        if self.matching is None:
            return None
        result = self.matching.evaluate(material_predictor(field, field_T_gt))
        self.curve.append([int(frame_index), float(time_s), result["matching_pct"]])
        self.mean_class_curve.append(
            [int(frame_index), float(time_s), result["matching_mean_class_pct"]]
        )
        return result

    def snapshot(self, field: nn.Module, field_T_gt: np.ndarray | None = None) -> dict | None:
        """Image-form maps of the current field (None when the object has no regions of interest),
        with `entropy`: (V, H, W) normalised entropy of the material branch, NaN off the object."""
        if self.images is None:
            return None
        # One query of the field gives both the labels and their uncertainty.
        probs = probability_predictor(field, field_T_gt)(self.images.surface_points())
        maps = self.images.label_maps(probs.argmax(axis=1).astype(np.int64))
        maps["entropy"] = self.images.value_image(entropy_of_probabilities(probs))
        return maps

    def uncertainty(self, field: nn.Module, field_T_gt: np.ndarray | None = None) -> dict | None:
        """AUROC and ECE of the field's uncertainty vs its errors on the matching samples
        (eval/uncertainty.py); None when the object has no regions of interest."""
        if self.matching is None:
            return None
        probs = probability_predictor(field, field_T_gt)(self.matching.points)
        return uncertainty_scores(probs, self.matching.labels)

    # ---------------------------------------------------------------- summaries
    def classifier_accuracy(self) -> dict:
        acc = ClassifierAccuracy()
        for _, finger, predicted, gt, *_ in self.touch_log:
            acc.update(finger, int(predicted), None if gt < 0 else int(gt))
        return acc.summary(self.class_names)

    def majority_baseline(self) -> dict:
        """Matching figures of the constant map of the ground truth's majority material.

        It is a material map on the true surface, so its shape-aware figure equals its plain
        one and shape metrics do not apply.
        """
        if self.matching is None:
            return {}
        if self._majority is None:  # fixed by the samples: computed once (logged, then reported)
            majority = self.matching.majority_class

            def constant(points: np.ndarray) -> np.ndarray:
                return np.full(len(points), majority, dtype=np.int64)

            out = self.matching.evaluate(constant)
            out["matching_pct_image"] = self.images.maps(constant)["matching_pct_image"]
            out["matching_mesh_pct"] = out["matching_pct"]
            out["matching_mesh_mean_class_pct"] = out["matching_mean_class_pct"]
            out["material"] = self.class_names[majority]
            self._majority = out
        return dict(self._majority)

    def field_metrics(
        self, field: nn.Module, bound: float, field_T_gt: np.ndarray | None = None
    ) -> tuple[dict, object | None]:
        """Matching (3D, shape-aware and image form, per class) and shape metrics of a field;
        also its mesh.

        The mesh is returned in the field's frame; shape metrics compare it in the
        ground-truth object frame. A field without a surface scores 0 on the shape-aware
        matching (every sample is far from any surface); a failed extraction leaves the
        shape-aware and shape figures None with a note, and every other figure stands.
        """
        out: dict = {"notes": []}
        predict = material_predictor(field, field_T_gt)
        if self.matching is not None:
            out.update(self.matching.evaluate(predict))
            out["matching_pct_image"] = self.images.maps(predict)["matching_pct_image"]
        mesh = None
        try:
            mesh = extract_mesh(field, bound, self.mesh_resolution, self.class_names)
        except NoDataError as exc:
            # An untrained field has no surface: the honest shape scores are zero.
            out.update({"fscore_5mm": 0.0, "chamfer_mm": None})
            out["notes"].append(str(exc))
            if self.matching is not None:
                out["matching_mesh_pct"] = out["matching_mesh_mean_class_pct"] = 0.0
            return out, None
        except (ValueError, RuntimeError, MemoryError) as exc:
            log.error("mesh extraction failed: %s", exc)
            out.update({"fscore_5mm": None, "chamfer_mm": None})
            if self.matching is not None:
                out["matching_mesh_pct"] = out["matching_mesh_mean_class_pct"] = None
            out["notes"].append(
                f"mesh extraction failed ({exc}): shape-aware matching and shape metrics not computed"
            )
            return out, None
        out.update(self.mesh_matching(mesh, field_T_gt))
        out.update(
            shape_metrics(
                mesh, self.obj.mesh, self.shape_samples, self.fscore_thresholds_mm, self.seed
            )
        )
        return out, mesh

    def mesh_matching(self, mesh, field_T_gt: np.ndarray | None = None) -> dict:
        """Shape-aware matching of a material mesh in the field's frame (empty without samples)."""
        if self.matching is None:
            return {}
        points = self.matching.points
        if field_T_gt is not None:
            points = transform_points(field_T_gt, points)
        labels, _ = labels_from_mesh(mesh, points, self.mesh_match_tolerance_m)
        result = self.matching.evaluate_labels(labels)
        return {
            "matching_mesh_pct": result["matching_pct"],
            "matching_mesh_mean_class_pct": result["matching_mean_class_pct"],
        }

    def final_metrics(
        self,
        field: nn.Module,
        bound: float,
        baseline: dict,
        field_T_gt: np.ndarray | None = None,
    ) -> tuple[dict, object | None]:
        """The scoring part of metrics.json for a finished field, and its mesh.

        `baseline` is `field_metrics` of the untrained field (taken before the run).
        """
        final, mesh = self.field_metrics(field, bound, field_T_gt)
        majority = self.majority_baseline()
        metrics = {key: final.get(key) for key in RUN_MATCHING_KEYS + SHAPE_KEYS}
        metrics["matching_curve"] = self.curve
        metrics["matching_mean_class_curve"] = self.mean_class_curve
        metrics["uncertainty"] = self.uncertainty(field, field_T_gt)
        metrics["classifier_accuracy"] = self.classifier_accuracy()
        metrics["materials_never_read"] = never_read(
            metrics["classifier_accuracy"], list(final.get("matching_per_class") or {})
        )
        metrics["baseline_majority"] = majority
        metrics["baseline"] = {k: baseline.get(k) for k in RUN_MATCHING_KEYS + SHAPE_KEYS[:2]}
        metrics["margin_over_majority"] = {
            key: final[key] - majority[key]
            for key in ("matching_mean_class_pct", "matching_pct", "matching_mesh_pct")
            if final.get(key) is not None and key in majority
        }
        recall = final.get("matching_per_class") or {}
        metrics["notes"] = (
            self.notes
            + final["notes"]
            + [
                f"no touch read {name} rightly ({why}); the map's recall of it {recall[name]:.1f} %"
                for name, why in (metrics["materials_never_read"] or {}).items()
            ]
        )
        return metrics, mesh

    # ---------------------------------------------------------------- resume
    def state(self) -> dict:
        return {
            "curve": self.curve,
            "mean_class_curve": self.mean_class_curve,
            "touch_log": self.touch_log,
        }

    def load_state(self, state: dict) -> None:
        self.curve = [list(row) for row in state.get("curve", [])]
        self.mean_class_curve = [list(row) for row in state.get("mean_class_curve", [])]
        # Logs from before the top class and abstention were kept: neither known.
        self.touch_log = [
            list(row) + [-1, ""][len(row) - 5 :] for row in state.get("touch_log", [])
        ]
