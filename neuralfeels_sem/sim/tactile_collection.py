"""A labelled tactile material data set from the simulated DIGITs (task=collect_tactile).

Writes `<root>/<sensor>/<material>/<id>.png` (ImageFolder style, the layout a user's real
DIGIT data would use), `<root>/_backgrounds/<sensor>.png` (each sensor's no-contact
frame, for the contact gate) and `<root>/manifest.json` (counts per sensor and class,
seeds, objects, renderer settings, command).

Balanced by construction: for every sensor (finger) and material it presses that
finger's DIGIT (same renderer seed as in sensor=sim, so the same background) against
random points of that material on primitives and library objects, with a press depth
drawn around the finger's firmness (the thumb presses less), a random roll about the
sensor axis and a small tilt; a frame is kept when its contact is large enough and at
least `min_purity` of the contact pixels are that material. A share
`edge_press_fraction` of presses is made with a gel edge instead (sensor tilted by
`edge_tilt_deg`), giving the strip imprints of the rig's tilted pads on narrow objects.
A share `feature_press_fraction` of touches is placed on a rim, edge or tight bend of the
object (`FeatureEdges`: a cup's rim, a lid's lip, a box's edge), pressed along the
bisector of the two faces: the ridge imprints area-uniform touches almost never give. The
two are drawn independently (a feature can be pressed with the gel's edge). The manifest
records each image's kind of press (`presses`: centre, edge, feature, feature+edge).

The classifier that trains on these images (perception/) never imports the simulator:
collection lives here, beside the renderers it drives.
"""

from __future__ import annotations

import json
import logging
import sys
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.digit import GEL_HEIGHT_M, GEL_WIDTH_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.geometry import rotation_matrix
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.backgrounds import finger_seed
from neuralfeels_sem.sim.digit_poses import pose_pressing, pose_pressing_edge
from neuralfeels_sem.sim.surface_curvature import SurfaceCurvature
from neuralfeels_sem.sim.touch_sources import (
    FeatureEdges,
    library_objects,
    primitive_objects,
    sample_feature_touch,
    sample_touch,
)

log = logging.getLogger(__name__)
TRIES_PER_SAMPLE = 40
BACKGROUND_DIR = "_backgrounds"
# Each image's kind of press, by (placed on a feature, pressed with the gel's edge).
PRESS_KINDS = {
    (False, False): "centre",
    (False, True): "edge",
    (True, False): "feature",
    (True, True): "feature+edge",
}
EDGE_BAND_M = 0.002  # an edge press uses a gel point within this of the gel border


@dataclass
class CollectionSettings:
    """task=collect_tactile's settings; their defaults and range checks are the task's
    schema (CollectTactileTaskConfig, configs/sensor_sim.py)."""

    samples_per_class_per_sensor: int
    sensors: list[str]
    library_objects: list[str]
    firmness_mm: dict[str, float]
    firmness_spread: float
    max_tilt_deg: float
    edge_press_fraction: float
    edge_tilt_deg: list[float]
    feature_press_fraction: float
    min_purity: float
    min_contact_px: int
    overwrite: bool
    seed: int
    tactile: dict  # DigitRenderer options


@dataclass
class _Written:
    """What has been written so far: counts, objects used, kinds of press, rejections."""

    counts: dict[str, dict[str, int]]
    used: dict[str, dict[str, defaultdict]]
    presses: dict[str, str] = field(default_factory=dict)
    curvatures: dict[str, float] = field(default_factory=dict)  # 1/m at each press
    edge_presses: int = 0
    rejected: int = 0


def collect_tactile(root: Path, class_names: list[str], settings: CollectionSettings) -> dict:
    """Write the data set under `root`; returns its root, total, counts and rejections."""
    sources = primitive_objects(class_names) + library_objects(
        list(settings.library_objects), class_names
    )
    by_class = _sources_by_class(sources, class_names)
    _prepare_root(root, bool(settings.overwrite))  # after every config check: no empty folder left
    jobs = _assign(by_class, settings)
    sensors = list(settings.sensors)
    written = _Written(
        counts={s: dict.fromkeys(class_names, 0) for s in sensors},
        used={s: {m: defaultdict(int) for m in class_names} for s in sensors},
    )
    (root / BACKGROUND_DIR).mkdir(exist_ok=True)
    for sensor in sensors:
        for material in class_names:
            (root / sensor / material).mkdir(parents=True, exist_ok=True)
    progress = tqdm(total=sum(len(j) for j in jobs.values()), desc="collect_tactile", unit="img")
    for source_index in sorted(jobs):
        _collect_from(
            sources[source_index],
            source_index,
            jobs[source_index],
            root,
            class_names,
            settings,
            written,
            progress,
        )
    progress.close()
    manifest = _manifest(class_names, settings, written)
    (root / "manifest.json").write_text(json.dumps(manifest, indent=2))
    log.info(
        "wrote %d tactile images to %s (%d renders rejected by the purity gate)",
        manifest["total"],
        root,
        written.rejected,
    )
    return {
        "root": str(root),
        "total": manifest["total"],
        "counts": written.counts,
        "rejected_renders": written.rejected,
    }


def _sources_by_class(sources: list[MaterialObject], class_names: list[str]) -> dict:
    by_class = {
        c: [i for i, o in enumerate(sources) if (o.face_labels == c).any()]
        for c in range(len(class_names))
    }
    missing = [class_names[c] for c, idx in by_class.items() if not idx]
    if missing:
        raise ConfigError(
            f"no object has material(s) {missing}: check materials= and task.library_objects"
        )
    return by_class


def _assign(by_class: dict, settings: CollectionSettings) -> dict[int, list[tuple[str, int, int]]]:
    """Every (sensor, class, k) sample's source object, drawn up front, so that each
    object's renderers are built once and every sample is repeatable from the seed."""
    rng = np.random.default_rng(int(settings.seed))
    jobs: dict[int, list[tuple[str, int, int]]] = defaultdict(list)
    for sensor in settings.sensors:
        for c in range(len(by_class)):
            for k in range(int(settings.samples_per_class_per_sensor)):
                jobs[int(rng.choice(by_class[c]))].append((sensor, c, k))
    return jobs


def _collect_from(
    obj: MaterialObject,
    source_index: int,
    jobs: list[tuple[str, int, int]],
    root: Path,
    class_names: list[str],
    settings: CollectionSettings,
    written: _Written,
    progress: tqdm,
) -> None:
    """Render and write every sample assigned to one source object (and the backgrounds)."""
    from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

    seed, sensors = int(settings.seed), list(settings.sensors)
    renderers = {
        s: DigitRenderer(obj, seed=finger_seed(seed, s), **settings.tactile) for s in sensors
    }
    features = FeatureEdges.of(obj) if float(settings.feature_press_fraction) > 0.0 else None
    curvature = SurfaceCurvature(obj.mesh, seed=seed)
    try:
        for sensor, c, k in jobs:
            sample_rng = np.random.default_rng([seed, source_index, sensors.index(sensor), c, k])
            render, on_feature, edge, touch = _press_until_clean(
                renderers[sensor],
                obj,
                sensor,
                c,
                sample_rng,
                features,
                class_names,
                settings,
                written,
            )
            path = root / sensor / class_names[c] / f"{k:05d}.png"
            cv2.imwrite(str(path), cv2.cvtColor(render.image, cv2.COLOR_RGB2BGR))
            key = path.relative_to(root).as_posix()
            written.presses[key] = PRESS_KINDS[(on_feature, edge)]
            written.curvatures[key] = round(curvature.at(touch.point, touch.normal), 3)
            written.counts[sensor][class_names[c]] += 1
            written.edge_presses += int(edge)
            written.used[sensor][class_names[c]][obj.name] += 1
            progress.update(1)
        for sensor, renderer in renderers.items():
            background = root / BACKGROUND_DIR / f"{sensor}.png"
            if not background.exists():
                cv2.imwrite(
                    str(background), cv2.cvtColor(renderer.background_image, cv2.COLOR_RGB2BGR)
                )
    finally:
        for renderer in renderers.values():
            renderer.close()


def _press_until_clean(
    renderer,
    obj: MaterialObject,
    sensor: str,
    c: int,
    rng: np.random.Generator,
    features: FeatureEdges | None,
    class_names: list[str],
    settings: CollectionSettings,
    written: _Written,
):
    """Press until a render has enough contact of purity `min_purity`; (render, on_feature,
    edge, touch)."""
    for _ in range(TRIES_PER_SAMPLE):
        # Drawn only when enabled, so data sets without feature presses repeat.
        on_feature = (
            features is not None
            and features.has(c)
            and rng.uniform() < float(settings.feature_press_fraction)
        )
        touch = sample_feature_touch(features, c, rng) if on_feature else sample_touch(obj, c, rng)
        pose, edge = _press_pose(touch, sensor, rng, settings)
        render = renderer.render(np.eye(4), pose)
        contact = int(render.contact_mask.sum())
        purity = float((render.material[render.contact_mask] == c).mean()) if contact else 0.0
        if contact >= int(settings.min_contact_px) and purity >= float(settings.min_purity):
            return render, on_feature, edge, touch
        written.rejected += 1
    raise DataError(
        f"could not get a clean {class_names[c]} touch on {obj.name} for {sensor} in "
        f"{TRIES_PER_SAMPLE} tries: lower task.min_purity or task.min_contact_px"
    )


def _press_pose(
    touch, sensor: str, rng: np.random.Generator, settings: CollectionSettings
) -> tuple[np.ndarray, bool]:
    """The sensor pose pressing `touch` (depth around the finger's firmness, tilted,
    rolled; with a gel edge for a share edge_press_fraction) and whether it is an edge press."""
    firmness = {f: float(v) / 1000.0 for f, v in settings.firmness_mm.items()}
    mean = firmness.get(sensor, 0.0015)
    press = float(
        np.clip(
            rng.normal(mean, float(settings.firmness_spread) * mean),
            2e-4,
            MAX_PENETRATION_M * 0.95,
        )
    )
    normal = tilted_normal(touch.normal, np.deg2rad(float(settings.max_tilt_deg)), rng)
    roll = rng.uniform(0, 2 * np.pi)
    edge_fraction = float(settings.edge_press_fraction)
    edge = edge_fraction > 0.0 and rng.uniform() < edge_fraction
    if not edge:
        return pose_pressing(touch.point, normal, press, roll), False
    edge_tilt = np.deg2rad(np.asarray(settings.edge_tilt_deg, dtype=np.float64))
    pose = pose_pressing_edge(
        touch.point, normal, press, edge_gel_point(rng), rng.uniform(*edge_tilt), roll
    )
    return pose, True


def tilted_normal(normal: np.ndarray, max_tilt_rad: float, rng: np.random.Generator) -> np.ndarray:
    axis = np.cross(normal, rng.normal(size=3))
    return rotation_matrix(axis, rng.uniform(0.0, max_tilt_rad)) @ normal


def edge_gel_point(rng: np.random.Generator) -> tuple[float, float]:
    """A random gel point near one of the four gel borders (metres from the centre)."""
    half_w, half_h = GEL_WIDTH_M / 2.0, GEL_HEIGHT_M / 2.0
    inset = rng.uniform(0.0, EDGE_BAND_M)
    if rng.uniform() < 0.5:  # long sides (x = +-half width), where the rig's strips lie
        return float(rng.choice([-1, 1]) * (half_w - inset)), float(
            rng.uniform(-half_h, half_h) * 0.7
        )
    return float(rng.uniform(-half_w, half_w) * 0.7), float(rng.choice([-1, 1]) * (half_h - inset))


def _prepare_root(root: Path, overwrite: bool) -> None:
    if root.exists() and not root.is_dir():
        raise DataError(f"task.root={root} is a file: pass a folder")
    if root.is_dir() and any(root.iterdir()) and not overwrite:
        raise DataError(
            f"task.root={root} is not empty: pass task.overwrite=true or another task.root"
        )
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(
            f"task.root={root} cannot be created ({exc.strerror}): pick a writable folder"
        ) from exc


def _manifest(class_names: list[str], settings: CollectionSettings, written: _Written) -> dict:
    sensors, counts, seed = list(settings.sensors), written.counts, int(settings.seed)
    return {
        "layout": "<root>/<sensor>/<material>/<id>.png; backgrounds in _backgrounds/<sensor>.png",
        "source": "sim",
        "classes": class_names,
        "sensors": sensors,
        "counts": counts,
        "total": int(sum(sum(v.values()) for v in counts.values())),
        "rejected_renders": written.rejected,
        "objects": {s: {m: dict(v) for m, v in written.used[s].items()} for s in sensors},
        "seed": seed,
        "renderer_seeds": {s: finger_seed(seed, s) for s in sensors},
        "renderer": settings.tactile,
        "firmness_mm": dict(settings.firmness_mm),
        "firmness_spread": float(settings.firmness_spread),
        "max_tilt_deg": float(settings.max_tilt_deg),
        "edge_press_fraction": float(settings.edge_press_fraction),
        "edge_tilt_deg": [float(v) for v in settings.edge_tilt_deg],
        "edge_presses": written.edge_presses,
        "feature_press_fraction": float(settings.feature_press_fraction),
        "press_counts": dict(sorted(Counter(written.presses.values()).items())),
        "presses": dict(sorted(written.presses.items())),
        # Largest surface curvature (1/m) at each press (sim/surface_curvature.py); NaN as null.
        "curvatures": {
            k: (v if np.isfinite(v) else None) for k, v in sorted(written.curvatures.items())
        },
        "min_purity": float(settings.min_purity),
        "min_contact_px": int(settings.min_contact_px),
        "image_size": [320, 240],
        "command": " ".join(["python", "run.py", *sys.argv[1:]]),
    }
