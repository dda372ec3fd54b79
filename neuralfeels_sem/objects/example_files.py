"""The example files `object=custom` loads by default, and the code that wrote them.

`neuralfeels_sem/objects/examples/two_tone_egg.obj` with `two_tone_egg.labels.json`
shows the custom formats: an 8 cm egg, plastic on top, metal below, an ignored seam.
Regenerate with `python -m neuralfeels_sem.objects.example_files`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from neuralfeels_sem.objects.label_files import write_labels_json
from neuralfeels_sem.objects.material_object import IGNORE

EXAMPLES_DIR = Path(__file__).resolve().parent / "examples"
SEAM_HALF_WIDTH = 0.0015  # m, faces this close to the equator are "ignore"


def two_tone_egg() -> tuple[trimesh.Trimesh, np.ndarray, tuple[str, ...]]:
    """(mesh, labels indexing classes, classes): 5120 faces, 8 x 5.6 x 5.6 cm."""
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    v = mesh.vertices
    # Egg profile: wider below the equator, long axis z.
    scale = np.where(v[:, 2] < 0, 0.028, 0.024)[:, None]
    mesh = trimesh.Trimesh(
        np.column_stack([v[:, :2] * scale, v[:, 2] * 0.04]), mesh.faces, process=False
    )
    classes = ("plastic", "metal")
    z = mesh.triangles_center[:, 2]
    labels = np.where(z > 0, 0, 1)
    labels[np.abs(z) < SEAM_HALF_WIDTH] = IGNORE
    return mesh, labels, classes


def write_two_tone_egg(directory: Path) -> tuple[Path, Path]:
    """Write the example mesh (obj) and its labels (json) into `directory`."""
    mesh, labels, classes = two_tone_egg()
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    mesh_path = directory / "two_tone_egg.obj"
    labels_path = directory / "two_tone_egg.labels.json"
    mesh.export(mesh_path, digits=6)
    write_labels_json(labels_path, labels, classes)
    return mesh_path, labels_path


if __name__ == "__main__":
    for path in write_two_tone_egg(EXAMPLES_DIR):
        print(f"wrote {path}")
