"""`object=custom`: any obj/ply/stl mesh with per-face labels, one material, or a drawn layout.

The mesh's duplicate vertices are merged (scanned meshes such as YCB's split them at
texture seams) before the watertight check; labels follow the file's face order.
`layout_seed` paints the generated objects' kind of layout (2-4 materials in patches,
bands, halves and inserts; layout_draw.py) onto the mesh: a user's own shape with a
material ground truth nobody tuned on.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.limits import MUJOCO_MAX_FACES
from neuralfeels_sem.objects.label_files import read_labels
from neuralfeels_sem.objects.layout_draw import draw_on_mesh
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.objects.materials import class_index, mass_and_friction, names_to_labels
from neuralfeels_sem.utils.paths import REPO_DIR

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".ply", ".stl")
HAND_SIZE_M = (0.05, 0.20)  # largest extent the rig turns and presses (as object=random's)


def resolve_path(path: str | Path, key: str) -> Path:
    """An existing file: absolute, or relative to the working directory, then the repository."""
    path = Path(path).expanduser()
    candidates = (path,) if path.is_absolute() else (Path.cwd() / path, REPO_DIR / path)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    if any(candidate.is_dir() for candidate in candidates):
        raise DataError(f"{key}={path} is a directory: give the path of a file inside it")
    raise DataError(f"{key}={path} does not exist: give the path of an existing file")


def sidecar_labels(mesh_path: Path) -> Path | None:
    """`<stem>.labels.json` or `<stem>.labels.npy` beside the mesh, if present."""
    for suffix in (".json", ".npy"):
        candidate = mesh_path.with_name(f"{mesh_path.stem}.labels{suffix}")
        if candidate.is_file():
            return candidate
    return None


def read_mesh(path: Path) -> trimesh.Trimesh:
    """Vertices and faces in file order, no processing, no visuals (so seams can merge)."""
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise DataError(f"object.mesh={path} must be one of {', '.join(MESH_SUFFIXES)}")
    try:
        # maintain_order keeps an obj's faces in file order (labels follow it).
        loaded = trimesh.load(path, force="mesh", process=False, maintain_order=True)
    except Exception as exc:  # trimesh raises many types for malformed files
        reason = f"{type(exc).__name__}: {(str(exc).strip().splitlines() or [''])[0]}"
        if isinstance(exc, ImportError):
            # trimesh falls back to decoding unknown bytes as text with an optional module
            reason = f"not a binary or text {path.suffix.lower()[1:]} file"
        raise DataError(f"object.mesh={path} is unreadable ({reason}): re-export it") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise DataError(f"object.mesh={path} holds no triangles: export a triangle mesh")
    check_mesh_size(path, np.asarray(loaded.vertices), len(loaded.faces))
    return trimesh.Trimesh(np.asarray(loaded.vertices), np.asarray(loaded.faces), process=False)


def check_mesh_size(path: Path, vertices: np.ndarray, num_faces: int) -> None:
    """Refuse NaN or infinite vertices and more faces than MuJoCo compiles, in one line."""
    bad = int((~np.isfinite(vertices)).any(axis=1).sum()) if len(vertices) else 0
    if bad:
        raise DataError(
            f"object.mesh={path} has {bad} vertices that are NaN or infinite: repair or re-export it"
        )
    if num_faces > MUJOCO_MAX_FACES:
        raise DataError(
            f"object.mesh={path} has {num_faces} faces, more than MuJoCo's {MUJOCO_MAX_FACES}: "
            "decimate it first (e.g. MeshLab's quadric edge collapse to 50000 faces)"
        )


def clean_mesh(
    mesh: trimesh.Trimesh, labels: np.ndarray, source: Path
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Merge duplicate vertices, drop degenerate/duplicate faces, check it is closed, orient it."""
    if len(labels) != len(mesh.faces):
        raise ValueError(f"clean_mesh: {len(labels)} labels for {len(mesh.faces)} faces")
    # process=True merges vertices by position only (no visuals) and keeps face order.
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
    keep = mesh.nondegenerate_faces() & mesh.unique_faces()  # both boolean masks
    mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    labels = labels[keep]
    if not mesh.is_watertight:
        edges = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
        raise DataError(
            f"object.mesh={source} is not watertight after merging duplicate vertices "
            f"({len(edges)} open edges): close its holes first (e.g. MeshLab, or trimesh.repair.fill_holes)"
        )
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
    if mesh.volume < 0:
        mesh.invert()
    return mesh, labels


@dataclass
class LaidOutObject(MaterialObject):
    """A custom mesh with a drawn layout: `layout` records the mesh name, size, layout
    seed, sub-seed used, materials and region kinds (metrics.json config.object_layout)."""

    layout: dict = field(default_factory=dict)


def label_sources_clash(
    labels: str | None, material: str | None, layout_seed: int | None
) -> str | None:
    """Why object.labels, material and layout_seed cannot be used together (None: they
    can): one source of labels at most. The object config's check and the loader's."""
    given = {"layout_seed": layout_seed, "labels": labels, "material": material}
    given = {k: v for k, v in given.items() if v is not None}
    if len(given) < 2:
        return None
    (a, x), (b, y), *_ = given.items()
    return f"object.{a}={x} and object.{b}={y} are both set: pick one"


def _check_options(
    labels: str | None, material: str | None, rescale_to: float | None, layout_seed: int | None
) -> None:
    """Reject a config that sets more than one label source, or a non-positive rescale."""
    clash = label_sources_clash(labels, material, layout_seed)
    if clash is not None:
        raise ConfigError(clash)
    if rescale_to is not None and rescale_to <= 0:
        raise ConfigError(f"object.rescale_to={rescale_to} must be > 0 metres, or null")
    if layout_seed is not None and (isinstance(layout_seed, bool) or layout_seed < 0):
        raise ConfigError(f"object.layout_seed={layout_seed} must be an integer >= 0, or null")


def _label_source(
    mesh_path: Path, labels: str | None, material: str | None, class_names: tuple[str, ...]
) -> tuple[int | None, Path | None]:
    """The whole-mesh class index (object.material), else the label file (given or beside the mesh)."""
    index = None
    if material is not None:
        index = class_index(material, class_names, what=f"object.material={material}")
    label_path = resolve_path(labels, "object.labels") if labels is not None else None
    if material is None and label_path is None:
        label_path = sidecar_labels(mesh_path)
        if label_path is None:
            raise ConfigError(
                f"object.mesh={mesh_path} has no labels: set object.labels=PATH (npy/json), "
                "object.material=NAME (one material) or object.layout_seed=K (a drawn layout)"
            )
    return index, label_path


def _face_labels(
    raw: trimesh.Trimesh,
    mesh_path: Path,
    index: int | None,
    label_path: Path | None,
    class_names: tuple[str, ...],
) -> np.ndarray:
    """One class index per face of `raw`: all `index`, or read from `label_path` (one per face)."""
    if index is not None:
        return np.full(len(raw.faces), index, dtype=np.int64)
    face_labels = read_labels(label_path, class_names)
    if len(face_labels) != len(raw.faces):
        raise DataError(
            f"label file {label_path} has {len(face_labels)} labels but object.mesh={mesh_path} has "
            f"{len(raw.faces)} faces: export one label per face"
        )
    return face_labels


def _centre_and_scale(clean: trimesh.Trimesh, mesh_path: Path, rescale_to: float | None) -> None:
    """Centre the mesh on its bounding box; rescale it, or warn when it is not hand-sized."""
    clean.apply_translation(-clean.bounds.mean(axis=0))
    if rescale_to is not None:
        clean.apply_scale(rescale_to / float(clean.extents.max()))
    elif not HAND_SIZE_M[0] <= clean.extents.max() <= HAND_SIZE_M[1]:
        log.warning(
            "object.mesh=%s is %.3f m across, outside the hand's %.2f-%.2f m: set object.rescale_to",
            mesh_path,
            clean.extents.max(),
            *HAND_SIZE_M,
        )


def _drawn_labels(
    clean: trimesh.Trimesh, seed: int, class_names: tuple[str, ...], mesh_path: Path, name: str
) -> tuple[np.ndarray, dict]:
    """Face labels of the layout drawn from `seed` on the cleaned, scaled mesh, and its record."""
    what = f"object.mesh={mesh_path}"
    names, drawn = draw_on_mesh(clean, seed, class_names, what)
    record = {"mesh": name, "size_m": round(float(clean.extents.max()), 4), **drawn}
    log.info("object=custom layout: %s", record)
    return names_to_labels(names, class_names, what=what), record


def load_custom_object(
    mesh: str,
    class_names: Sequence[str],
    labels: str | None = None,
    material: str | None = None,
    rescale_to: float | None = None,
    name: str | None = None,
    aruco: object = None,
    layout_seed: int | None = None,
) -> MaterialObject:
    """Load a mesh file as a MaterialObject centred on its bounding-box centre.

    Labels come from `labels` (npy/json), or `material` for the whole mesh, or a layout
    drawn from `layout_seed` over every class (a LaidOutObject), or a
    `<stem>.labels.{json,npy}` file beside the mesh. `rescale_to` scales the mesh
    uniformly so its largest extent is that many metres. `aruco` (object.aruco, the
    marker layout) is read by sensor=real from the config; it is accepted here only so the
    object config instantiates.
    """
    class_names = tuple(class_names)
    _check_options(labels, material, rescale_to, layout_seed)
    mesh_path = resolve_path(mesh, "object.mesh")
    drawn = layout_seed is not None
    index, label_path = (
        (0, None) if drawn else _label_source(mesh_path, labels, material, class_names)
    )
    raw = read_mesh(mesh_path)
    # a drawn layout is painted once the mesh is cleaned and scaled (its regions are in metres)
    face_labels = _face_labels(raw, mesh_path, index, label_path, class_names)
    clean, face_labels = clean_mesh(raw, face_labels, mesh_path)
    _centre_and_scale(clean, mesh_path, rescale_to)
    name = name or mesh_path.stem
    record = None
    if drawn:
        face_labels, record = _drawn_labels(clean, int(layout_seed), class_names, mesh_path, name)
    body = None if record is None else record["materials"][0]
    mass, friction = mass_and_friction(
        float(clean.volume), np.asarray(clean.area_faces), face_labels, class_names, body
    )
    parts = dict(name=name, mesh=clean, face_labels=face_labels, class_names=class_names)
    if record is None:
        return MaterialObject(**parts, mass_kg=mass, friction=friction)
    return LaidOutObject(**parts, mass_kg=mass, friction=friction, layout=record)
