"""Read and write per-face material label files (npy or json).

Formats, one entry per face in the mesh file's face order:
- npy: int array (indexes the configured `materials`, -1 = ignore) or str array of names;
- json: a list of ints or of names, or {"classes": [names], "faces": [ints indexing classes]}.
The name "ignore" (and -1) marks faces outside the regions of interest.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.objects.material_object import IGNORE
from neuralfeels_sem.objects.materials import IGNORE_NAME, names_to_labels


def _from_ints(values: np.ndarray, n_classes: int, path: Path, classes_hint: str) -> np.ndarray:
    bad = (values != IGNORE) & ((values < 0) | (values >= n_classes))
    if bad.any():
        raise DataError(
            f"label file {path}: face label {int(values[bad][0])} is outside -1..{n_classes - 1} "
            f"(the {classes_hint}): fix the file or use material names"
        )
    return values.astype(np.int64)


def _from_names(names: Sequence[str], class_names: Sequence[str], path: Path) -> np.ndarray:
    try:
        return names_to_labels(names, class_names, what=f"label file {path}")
    except ConfigError as exc:  # a name in a file is a data problem, not a config one
        raise DataError(str(exc)) from exc


def _from_json(data: object, class_names: Sequence[str], path: Path) -> np.ndarray:
    if isinstance(data, dict):
        if set(data) != {"classes", "faces"}:
            raise DataError(
                f'label file {path}: a json object needs exactly the keys "classes" and "faces"'
            )
        classes = [str(c) for c in data["classes"]]
        local = _from_ints(
            np.asarray(data["faces"]), len(classes), path, f"{len(classes)} classes in the file"
        )
        names = np.array([*classes, IGNORE_NAME])[local]  # -1 picks the appended "ignore"
        return _from_names(names, class_names, path)
    if isinstance(data, list) and all(isinstance(v, str) for v in data):
        return _from_names(data, class_names, path)
    if isinstance(data, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in data):
        return _from_ints(
            np.asarray(data, dtype=np.int64), len(class_names), path, "configured materials"
        )
    raise DataError(f"label file {path}: expected a list of ints or names, or {{classes, faces}}")


def read_labels(path: Path, class_names: Sequence[str]) -> np.ndarray:
    """(F,) int64 labels indexing `class_names` (-1 = ignore); DataError on a bad file."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"label file {path} does not exist: check object.labels")
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            values = np.load(path, allow_pickle=False)
        elif suffix == ".json":
            values = json.loads(path.read_text())
        else:
            raise DataError(f"label file {path} must end in .npy or .json")
    except (OSError, ValueError) as exc:
        raise DataError(
            f"label file {path} is unreadable ({type(exc).__name__}): re-export it"
        ) from exc
    if suffix == ".json":
        return _from_json(values, class_names, path)
    if values.ndim != 1:
        raise DataError(
            f"label file {path}: expected one label per face, got an array of shape {values.shape}"
        )
    if values.dtype.kind in "US":
        return _from_names(values.astype(str), class_names, path)
    if values.dtype.kind in "iu":
        return _from_ints(values.astype(np.int64), len(class_names), path, "configured materials")
    raise DataError(f"label file {path}: dtype {values.dtype} is neither int nor str")


def write_labels_json(path: Path, labels: np.ndarray, class_names: Sequence[str]) -> None:
    """Write labels in the self-describing {"classes", "faces"} json form."""
    Path(path).write_text(
        json.dumps({"classes": list(class_names), "faces": [int(v) for v in labels]})
    )
