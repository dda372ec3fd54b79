"""task=collect_tactile: a labelled tactile material data set from the simulated DIGITs.

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
"""

from __future__ import annotations

import json
import logging
import sys
from collections import Counter, defaultdict
from pathlib import Path

import cv2
import numpy as np
from hydra.utils import to_absolute_path
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from neuralfeels_sem.core.digit import GEL_HEIGHT_M, GEL_WIDTH_M, MAX_PENETRATION_M
from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.geometry import rotation_matrix
from neuralfeels_sem.sim.backgrounds import finger_seed
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


def _tilted(normal: np.ndarray, max_tilt_rad: float, rng: np.random.Generator) -> np.ndarray:
    axis = np.cross(normal, rng.normal(size=3))
    return rotation_matrix(axis, rng.uniform(0.0, max_tilt_rad)) @ normal


# Each image's kind of press, by (placed on a feature, pressed with the gel's edge).
PRESS_KINDS = {
    (False, False): "centre",
    (False, True): "edge",
    (True, False): "feature",
    (True, True): "feature+edge",
}
EDGE_BAND_M = 0.002  # an edge press uses a gel point within this of the gel border


def _edge_gel_point(rng: np.random.Generator) -> tuple[float, float]:
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


def run(cfg: DictConfig) -> dict:
    from neuralfeels_sem.sim.tactile_renderer import (
        DigitRenderer,
        pose_pressing,
        pose_pressing_edge,
    )

    task = cfg.task
    class_names = list(cfg.materials)
    root = Path(to_absolute_path(str(task.root)))
    sensors = list(task.sensors)
    per_group = int(task.samples_per_class_per_sensor)
    seed = int(task.seed)
    tactile_options = OmegaConf.to_container(task.tactile, resolve=True)

    sources = primitive_objects(class_names) + library_objects(
        list(task.library_objects), class_names
    )
    by_class = {
        c: [i for i, o in enumerate(sources) if (o.face_labels == c).any()]
        for c in range(len(class_names))
    }
    missing = [class_names[c] for c, idx in by_class.items() if not idx]
    if missing:
        raise ConfigError(
            f"no object has material(s) {missing}: check materials= and task.library_objects"
        )
    _prepare_root(root, bool(task.overwrite))  # after every config check: no empty folder left

    # Assign every (sensor, class, k) sample to a source object up front, so that each
    # object's renderers are built once and every sample is repeatable from the seed.
    rng = np.random.default_rng(seed)
    jobs: dict[int, list[tuple[str, int, int]]] = defaultdict(list)
    for sensor in sensors:
        for c in range(len(class_names)):
            for k in range(per_group):
                jobs[int(rng.choice(by_class[c]))].append((sensor, c, k))

    counts = {s: dict.fromkeys(class_names, 0) for s in sensors}
    used = {s: {m: defaultdict(int) for m in class_names} for s in sensors}
    rejected = 0
    (root / BACKGROUND_DIR).mkdir(exist_ok=True)
    for sensor in sensors:
        for material in class_names:
            (root / sensor / material).mkdir(parents=True, exist_ok=True)
    firmness = {f: float(v) / 1000.0 for f, v in task.firmness_mm.items()}
    max_tilt = np.deg2rad(float(task.max_tilt_deg))
    edge_fraction = float(task.edge_press_fraction)
    edge_tilt = np.deg2rad(np.asarray(task.edge_tilt_deg, dtype=np.float64))
    feature_fraction = float(task.feature_press_fraction)
    edge_presses = 0
    presses: dict[str, str] = {}
    progress = tqdm(total=sum(len(j) for j in jobs.values()), desc="collect_tactile", unit="img")
    for source_index in sorted(jobs):
        obj = sources[source_index]
        renderers = {
            s: DigitRenderer(obj, seed=finger_seed(seed, s), **tactile_options) for s in sensors
        }
        features = FeatureEdges.of(obj) if feature_fraction > 0.0 else None
        try:
            for sensor, c, k in jobs[source_index]:
                sample_rng = np.random.default_rng(
                    [seed, source_index, sensors.index(sensor), c, k]
                )
                for _ in range(TRIES_PER_SAMPLE):
                    # Drawn only when enabled, so data sets without feature presses repeat.
                    on_feature = (
                        features is not None
                        and features.has(c)
                        and sample_rng.uniform() < feature_fraction
                    )
                    touch = (
                        sample_feature_touch(features, c, sample_rng)
                        if on_feature
                        else sample_touch(obj, c, sample_rng)
                    )
                    mean = firmness.get(sensor, 0.0015)
                    press = float(
                        np.clip(
                            sample_rng.normal(mean, float(task.firmness_spread) * mean),
                            2e-4,
                            MAX_PENETRATION_M * 0.95,
                        )
                    )
                    normal = _tilted(touch.normal, max_tilt, sample_rng)
                    roll = sample_rng.uniform(0, 2 * np.pi)
                    edge = edge_fraction > 0.0 and sample_rng.uniform() < edge_fraction
                    if edge:
                        pose = pose_pressing_edge(
                            touch.point,
                            normal,
                            press,
                            _edge_gel_point(sample_rng),
                            sample_rng.uniform(*edge_tilt),
                            roll,
                        )
                    else:
                        pose = pose_pressing(touch.point, normal, press, roll)
                    render = renderers[sensor].render(np.eye(4), pose)
                    contact = int(render.contact_mask.sum())
                    purity = (
                        float((render.material[render.contact_mask] == c).mean())
                        if contact
                        else 0.0
                    )
                    if contact >= int(task.min_contact_px) and purity >= float(task.min_purity):
                        break
                    rejected += 1
                else:
                    raise DataError(
                        f"could not get a clean {class_names[c]} touch on {obj.name} for {sensor} in "
                        f"{TRIES_PER_SAMPLE} tries: lower task.min_purity or task.min_contact_px"
                    )
                path = root / sensor / class_names[c] / f"{k:05d}.png"
                cv2.imwrite(str(path), cv2.cvtColor(render.image, cv2.COLOR_RGB2BGR))
                presses[path.relative_to(root).as_posix()] = PRESS_KINDS[(on_feature, edge)]
                counts[sensor][class_names[c]] += 1
                edge_presses += int(edge)
                used[sensor][class_names[c]][obj.name] += 1
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
    progress.close()

    manifest = {
        "layout": "<root>/<sensor>/<material>/<id>.png; backgrounds in _backgrounds/<sensor>.png",
        "source": "sim",
        "classes": class_names,
        "sensors": sensors,
        "counts": counts,
        "total": int(sum(sum(v.values()) for v in counts.values())),
        "rejected_renders": rejected,
        "objects": {s: {m: dict(v) for m, v in used[s].items()} for s in sensors},
        "seed": seed,
        "renderer_seeds": {s: finger_seed(seed, s) for s in sensors},
        "renderer": tactile_options,
        "firmness_mm": dict(task.firmness_mm),
        "firmness_spread": float(task.firmness_spread),
        "max_tilt_deg": float(task.max_tilt_deg),
        "edge_press_fraction": edge_fraction,
        "edge_tilt_deg": [float(v) for v in task.edge_tilt_deg],
        "edge_presses": edge_presses,
        "feature_press_fraction": feature_fraction,
        "press_counts": dict(sorted(Counter(presses.values()).items())),
        "presses": dict(sorted(presses.items())),
        "min_purity": float(task.min_purity),
        "min_contact_px": int(task.min_contact_px),
        "image_size": [320, 240],
        "command": " ".join(["python", "run.py", *sys.argv[1:]]),
    }
    (root / "manifest.json").write_text(json.dumps(manifest, indent=2))
    log.info(
        "wrote %d tactile images to %s (%d renders rejected by the purity gate)",
        manifest["total"],
        root,
        rejected,
    )
    return {
        "root": str(root),
        "total": manifest["total"],
        "counts": counts,
        "rejected_renders": rejected,
    }
