"""Matching percentage in 3D (docs/design.md "Matching percentage").

Ground-truth surface samples are drawn once (area-uniform over the regions of interest,
i.e. faces whose label is not IGNORE, with a fixed seed), so scores over a run compare.
On them:
- `matching_pct`: share of samples whose predicted class equals the ground truth (the
  paper's figure; a constant map of the majority material scores that material's share);
- `matching_mean_class_pct`: mean over the classes present of each class's recall, so
  every material counts the same whatever its area (a constant map scores 100 / classes);
- `matching_miou_pct`: mean intersection-over-union over the classes present.
A prediction of NO_PREDICTION (-1) is wrong for every class: the shape-aware form uses it
for samples with no reconstructed surface near them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import cKDTree

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject

Predictor = Callable[[np.ndarray], np.ndarray]
NO_PREDICTION = -1  # a sample the map gives no class (no surface near it): wrong for every class


def sample_faces_uniform(
    vertices: np.ndarray, faces: np.ndarray, face_ids: np.ndarray, count: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform points on the faces `face_ids`: (points (count, 3), face index (count,))."""
    tri = vertices[faces[face_ids]]  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        raise ValueError("faces to sample have zero total area")
    rng = np.random.default_rng(seed)
    chosen = rng.choice(len(face_ids), size=count, p=area / area.sum())
    # Uniform barycentric coordinates: reflect (u, v) outside the triangle back inside.
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    t = tri[chosen]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    return points, face_ids[chosen]


def predict_labels(predict: Predictor, points: np.ndarray) -> np.ndarray:
    """Call a predictor and check it returns one integer class per point."""
    pred = np.asarray(predict(points))
    if pred.shape != (len(points),):
        raise ValueError(
            f"predictor returned shape {pred.shape} for {len(points)} points; expected ({len(points)},)"
        )
    if not np.issubdtype(pred.dtype, np.integer):
        raise ValueError(f"predictor must return integer class indices, got {pred.dtype}")
    return pred.astype(np.int64)


def label_scores(labels: np.ndarray, pred: np.ndarray, class_names: tuple[str, ...]) -> dict:
    """Matching, per-class recall, mean-class recall and mean IoU (0-100) of `pred` vs `labels`.

    Only classes present in `labels` count towards the means; predicting an absent class
    lowers the recall and IoU of the class it replaced.
    """
    if pred.shape != labels.shape:
        raise ValueError(f"predictions {pred.shape} do not match samples {labels.shape}")
    recall, iou = {}, {}
    for index in np.unique(labels):
        truth, said = labels == index, pred == index
        name = class_names[int(index)]
        recall[name] = float(100.0 * np.mean(said[truth]))
        iou[name] = float(100.0 * np.sum(truth & said) / np.sum(truth | said))
    return {
        "matching_pct": float(100.0 * np.mean(pred == labels)),
        "matching_per_class": recall,
        "matching_mean_class_pct": float(np.mean(list(recall.values()))),
        "matching_miou_pct": float(np.mean(list(iou.values()))),
    }


class MatchingEvaluator:
    """Scores a material predictor against one object's ground truth on fixed surface samples."""

    def __init__(self, obj: MaterialObject, num_samples: int = 20000, seed: int = 0) -> None:
        if num_samples < 1:
            raise ValueError(f"num_samples={num_samples} must be >= 1")
        self.class_names = tuple(obj.class_names)
        roi = np.flatnonzero(obj.face_labels != IGNORE)
        if len(roi) == 0:
            raise NoDataError(
                f"object {obj.name!r} has no region of interest (every face label is ignore); "
                "matching percentage cannot be computed: label some faces with a material"
            )
        vertices = np.asarray(obj.mesh.vertices, dtype=np.float64)
        faces = np.asarray(obj.mesh.faces)
        self.points, self.faces = sample_faces_uniform(vertices, faces, roi, num_samples, seed)
        self.labels = obj.face_labels[self.faces]
        present = np.unique(self.labels)
        self.notes: list[str] = []
        if len(present) == 1:
            self.notes.append(
                f"the regions of interest hold one material ({self.class_names[present[0]]}): "
                "mean-class matching is that material's recall, and a constant map scores 100 %"
            )

    @property
    def majority_class(self) -> int:
        """The ground truth's majority material over the samples (by area); ties go to the lower index."""
        return int(np.bincount(self.labels).argmax())

    def predictions(self, predict: Predictor) -> np.ndarray:
        return predict_labels(predict, self.points)

    def score(self, predict: Predictor) -> float:
        """Matching percentage, 0-100."""
        return self.evaluate(predict)["matching_pct"]

    def per_class(self, predict: Predictor) -> dict[str, float]:
        """Recall (0-100) per material present in the regions of interest."""
        return self.evaluate(predict)["matching_per_class"]

    def evaluate(self, predict: Predictor) -> dict:
        """Every matching figure from one call of the predictor (keys as `label_scores`)."""
        return self.evaluate_labels(self.predictions(predict))

    def nearest_scores(self, points: np.ndarray, labels: np.ndarray) -> dict:
        """Every matching figure of the map that gives each sample the label of the nearest
        of `points` (N, 3) (a nearest-point, Voronoi, map of labelled points)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        labels = np.asarray(labels, dtype=np.int64).reshape(-1)
        if len(points) == 0 or len(points) != len(labels):
            raise ValueError(
                f"need one label per point and at least one point; got {len(points)} points, "
                f"{len(labels)} labels"
            )
        return self.evaluate_labels(labels[cKDTree(points).query(self.points)[1]])

    def evaluate_labels(self, pred: np.ndarray) -> dict:
        """Every matching figure of predictions already made at `self.points` (NO_PREDICTION allowed)."""
        return label_scores(self.labels, np.asarray(pred, dtype=np.int64), self.class_names)
