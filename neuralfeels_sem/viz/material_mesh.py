"""The reconstructed mesh coloured by predicted material (material_mesh.ply)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import trimesh

from neuralfeels_sem.core.palette import colorize
from neuralfeels_sem.eval.matching import Predictor, predict_labels
from neuralfeels_sem.utils.atomic import atomic_write


def color_mesh(
    mesh: trimesh.Trimesh, vertex_labels: np.ndarray, class_names: Sequence[str]
) -> trimesh.Trimesh:
    """A copy of `mesh` with vertex colours from per-vertex class labels."""
    vertex_labels = np.asarray(vertex_labels)
    if vertex_labels.shape != (len(mesh.vertices),):
        raise ValueError(f"{vertex_labels.shape} labels for {len(mesh.vertices)} vertices")
    rgb = colorize(vertex_labels, class_names)
    rgba = np.concatenate([rgb, np.full((len(rgb), 1), 255, dtype=np.uint8)], axis=1)
    return trimesh.Trimesh(
        mesh.vertices.copy(), mesh.faces.copy(), vertex_colors=rgba, process=False
    )


def save_material_mesh(
    mesh: trimesh.Trimesh, predict: Predictor, class_names: Sequence[str], path: Path | str
) -> Path:
    """Predict the material at every vertex and write a vertex-coloured PLY."""
    if len(mesh.vertices) == 0:
        raise ValueError("cannot colour an empty mesh")
    labels = predict_labels(predict, np.asarray(mesh.vertices, dtype=np.float64))
    path = Path(path)
    with atomic_write(path, "wb") as f:
        color_mesh(mesh, labels, class_names).export(f, file_type=path.suffix.lstrip(".") or "ply")
    return path
