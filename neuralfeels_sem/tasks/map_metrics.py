"""Scoring during and after a mapping run: what goes into metrics.json and the pictures.

`RunScorer` holds the fixed ground-truth samples, the matching curve, the touch log
(every classified touch with its ground truth) and progression snapshots. Its state is
plain data so a checkpoint can carry it and a resumed run loses none of it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.errors import NoDataError
from neuralfeels_sem.eval.classifier_metrics import ClassifierAccuracy, gt_material_of
from neuralfeels_sem.eval.image_matching import ImageMatcher
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.shape import shape_metrics
from neuralfeels_sem.fields.semantic_field import evaluate_chunked
from neuralfeels_sem.mapping.mesh import extract_mesh
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.sensors.frame import Frame
from neuralfeels_sem.utils.geometry import transform_points

log = logging.getLogger(__name__)


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
        self.fscore_thresholds_mm = list(fscore_thresholds_mm)
        self.shape_samples = shape_samples
        self.mesh_resolution = mesh_resolution
        self.seed = seed
        self.curve: list[list[float]] = []  # [frame_index, time_s, matching_pct]
        self.touch_log: list[list] = []  # [frame_index, finger, predicted, gt or -1, confidence]

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
                ]
            )

    def score(
        self,
        field: nn.Module,
        frame_index: int,
        time_s: float,
        field_T_gt: np.ndarray | None = None,
    ) -> float | None:
        if self.matching is None:
            return None
        pct = self.matching.score(material_predictor(field, field_T_gt))
        self.curve.append([int(frame_index), float(time_s), pct])
        return pct

    def snapshot(self, field: nn.Module, field_T_gt: np.ndarray | None = None) -> dict | None:
        """Image-form maps of the current field (None when the object has no regions of interest)."""
        if self.images is None:
            return None
        return self.images.maps(material_predictor(field, field_T_gt))

    # ---------------------------------------------------------------- summaries
    def classifier_accuracy(self) -> dict:
        acc = ClassifierAccuracy()
        for _, finger, predicted, gt, _ in self.touch_log:
            acc.update(finger, int(predicted), None if gt < 0 else int(gt))
        return acc.summary(self.class_names)

    def field_metrics(
        self, field: nn.Module, bound: float, field_T_gt: np.ndarray | None = None
    ) -> tuple[dict, object | None]:
        """Matching (3D + image form, per class) and shape metrics of a field; also its mesh.

        The mesh is returned in the field's frame; shape metrics compare it in the
        ground-truth object frame.
        """
        out: dict = {}
        predict = material_predictor(field, field_T_gt)
        if self.matching is not None:
            result = self.matching.evaluate(predict)
            out["matching_pct"] = result["matching_pct"]
            out["matching_per_class"] = result["per_class"]
            out["matching_pct_image"] = self.images.maps(predict)["matching_pct_image"]
        mesh = None
        try:
            mesh = extract_mesh(field, bound, self.mesh_resolution, self.class_names)
            shape = shape_metrics(
                mesh, self.obj.mesh, self.shape_samples, self.fscore_thresholds_mm, self.seed
            )
            out.update(shape)
        except NoDataError as exc:
            # An untrained field has no surface: the honest shape score is zero.
            out.update({"fscore_5mm": 0.0, "chamfer_mm": None, "shape_note": str(exc)})
        return out, mesh

    # ---------------------------------------------------------------- resume
    def state(self) -> dict:
        return {"curve": self.curve, "touch_log": self.touch_log}

    def load_state(self, state: dict) -> None:
        self.curve = [list(row) for row in state.get("curve", [])]
        self.touch_log = [list(row) for row in state.get("touch_log", [])]
