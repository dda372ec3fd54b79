"""Matching percentage in 3D (DESIGN.md "Matching percentage").

Score = share of ground-truth surface samples (area-uniform over the regions of interest,
i.e. faces whose label is not IGNORE, with a fixed seed) whose predicted class equals the
ground-truth class. The samples are drawn once, so scores over a run are comparable.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from neuralfeels_sem.errors import NoDataError
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject

Predictor = Callable[[np.ndarray], np.ndarray]


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

    def predictions(self, predict: Predictor) -> np.ndarray:
        return predict_labels(predict, self.points)

    def score(self, predict: Predictor) -> float:
        """Matching percentage, 0-100."""
        return self.score_labels(self.predictions(predict))

    def score_labels(self, pred: np.ndarray) -> float:
        """Matching percentage of predictions already made at `self.points`."""
        if pred.shape != self.labels.shape:
            raise ValueError(f"predictions {pred.shape} do not match samples {self.labels.shape}")
        return float(100.0 * np.mean(pred == self.labels))

    def per_class(self, predict: Predictor) -> dict[str, float]:
        """Recall (0-100) per material present in the regions of interest."""
        return self.per_class_labels(self.predictions(predict))

    def per_class_labels(self, pred: np.ndarray) -> dict[str, float]:
        out = {}
        for index, name in enumerate(self.class_names):
            mask = self.labels == index
            if mask.any():
                out[name] = float(100.0 * np.mean(pred[mask] == index))
        return out

    def evaluate(self, predict: Predictor) -> dict:
        """Both numbers from one call of the predictor: {'matching_pct', 'per_class'}."""
        pred = self.predictions(predict)
        return {"matching_pct": self.score_labels(pred), "per_class": self.per_class_labels(pred)}
