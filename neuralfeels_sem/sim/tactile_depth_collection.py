"""Training data for the tactile depth network (task=train_tactile_depth), rendered here.

Each sample presses one DIGIT against a random point of a primitive or library object:
press depth drawn around a finger's firmness (as task=collect_tactile does) or uniformly
over the gel's range, a tilt, a roll, a share of gel-edge presses (the strips of the rig's
tilted pads) and a share of near misses that stop short of the gel (soft materials still
shade the gel there, without contact). A sample keeps the gel's shading as a change over
the background (`DigitRenderer.render_change`) and its ground truth; the trainer composes
frames = background + change + noise over a pool of backgrounds (`depth_backgrounds`:
procedural ones and real empty DIGIT frames), which is exactly the renderer's image model.

The network that learns from these (perception/tactile_depth_net) never imports the
simulator: the task hands it plain arrays.
"""

from __future__ import annotations

import logging
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from neuralfeels_sem.core.digit import GEL_DISTANCE_M, MAX_PENETRATION_M
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.backgrounds import load_background, procedural_background
from neuralfeels_sem.sim.digit_poses import pose_pressing, pose_pressing_edge
from neuralfeels_sem.sim.tactile_collection import edge_gel_point, tilted_normal
from neuralfeels_sem.sim.touch_sources import library_objects, primitive_objects, sample_touch

log = logging.getLogger(__name__)
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


@dataclass
class DepthPressSettings:
    """How presses are drawn; defaults and range checks: TrainTactileDepthTaskConfig
    (configs/tactile_depth.py)."""

    sensors: list[str]
    library_objects: list[str]
    firmness_mm: dict[str, float]
    firmness_spread: float
    uniform_press_fraction: float
    min_press_mm: float
    miss_fraction: float
    max_gap_mm: float
    max_tilt_deg: float
    edge_press_fraction: float
    edge_tilt_deg: list[float]
    texture_scale: float


@dataclass
class DepthSamples:
    """Rendered presses: shading change, ground truth and which finger's press each is."""

    change: np.ndarray  # (N, 320, 240, 3) int16 grey levels over the background
    press_mm: np.ndarray  # (N, 320, 240) float16 press into the gel, 0 off-contact
    finger: list[str]
    objects: dict[str, int] = field(default_factory=dict)

    @property
    def contact(self) -> np.ndarray:
        return self.press_mm > 0

    def gt_depth(self, i: int) -> np.ndarray:
        """Sample i's depth in the simulator's convention (metres along +z, 0 off-contact)."""
        press = self.press_mm[i].astype(np.float32)
        return np.where(press > 0, GEL_DISTANCE_M - press / 1000.0, 0.0).astype(np.float32)


def render_depth_samples(
    count: int, class_names: list[str], settings: DepthPressSettings, seed: int
) -> DepthSamples:
    """`count` presses, the same for the same seed; fingers are taken in turn."""
    sources = primitive_objects(class_names) + library_objects(
        list(settings.library_objects), class_names
    )
    rng = np.random.default_rng(seed)
    jobs: dict[int, list[int]] = defaultdict(list)
    for k in range(count):
        jobs[int(rng.integers(len(sources)))].append(k)
    change = np.zeros((count, 320, 240, 3), np.int16)
    press_mm = np.zeros((count, 320, 240), np.float16)
    fingers = [settings.sensors[k % len(settings.sensors)] for k in range(count)]
    used: Counter = Counter()
    progress = tqdm(total=count, desc="render presses", unit="img")
    for index in sorted(jobs):
        _render_object(
            sources[index], index, jobs[index], seed, settings, fingers, change, press_mm
        )
        used[sources[index].name] += len(jobs[index])
        progress.update(len(jobs[index]))
    progress.close()
    return DepthSamples(change, press_mm, fingers, dict(sorted(used.items())))


def _render_object(
    obj: MaterialObject,
    index: int,
    samples: list[int],
    seed: int,
    settings: DepthPressSettings,
    fingers: list[str],
    change: np.ndarray,
    press_mm: np.ndarray,
) -> None:
    from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

    # The background is never used (only the change is kept); a flat one costs nothing.
    flat = np.zeros((320, 240, 3), np.uint8)
    renderer = DigitRenderer(
        obj, background=flat, noise_std=0.0, seed=seed + index, texture_scale=settings.texture_scale
    )
    labels = np.unique(obj.face_labels)
    try:
        for k in samples:
            rng = np.random.default_rng([seed, k])
            touch = sample_touch(obj, int(rng.choice(labels)), rng)
            pose = _press_pose(touch, fingers[k], rng, settings)
            delta, truth = renderer.render_change(np.eye(4), pose)
            change[k] = np.clip(np.rint(delta), -32768, 32767).astype(np.int16)
            press = np.where(truth.contact_mask, (GEL_DISTANCE_M - truth.depth) * 1000.0, 0.0)
            # float16 rounds a press of a few nanometres to 0: keep it in contact.
            press_mm[k] = np.where(truth.contact_mask, np.maximum(press, 1e-4), 0.0)
    finally:
        renderer.close()


def _press_pose(touch, finger: str, rng: np.random.Generator, settings: DepthPressSettings):
    """A pressing (or, for a share miss_fraction, a nearly touching) sensor pose."""
    top_mm = MAX_PENETRATION_M * 1000.0 * 0.95
    if rng.uniform() < settings.miss_fraction:
        press_mm = -rng.uniform(0.0, settings.max_gap_mm)
    elif rng.uniform() < settings.uniform_press_fraction:
        press_mm = rng.uniform(settings.min_press_mm, top_mm)
    else:
        mean = float(settings.firmness_mm.get(finger, 1.5))
        press_mm = rng.normal(mean, settings.firmness_spread * mean)
        press_mm = float(np.clip(press_mm, settings.min_press_mm, top_mm))
    normal = tilted_normal(touch.normal, np.deg2rad(settings.max_tilt_deg), rng)
    roll = rng.uniform(0, 2 * np.pi)
    if rng.uniform() >= settings.edge_press_fraction:
        return pose_pressing(touch.point, normal, press_mm / 1000.0, roll)
    tilt = np.deg2rad(rng.uniform(*settings.edge_tilt_deg))
    return pose_pressing_edge(
        touch.point, normal, press_mm / 1000.0, edge_gel_point(rng), tilt, roll
    )


def depth_backgrounds(
    procedural_seeds: list[int], real_dir: str | Path | None, real_part: tuple[int, int]
) -> tuple[np.ndarray, list[str]]:
    """(K, 320, 240, 3) uint8 empty DIGIT frames and their names: procedural ones of the
    given seeds, plus the real images of `real_dir` (if it exists) whose sorted index i has
    i % real_part[1] in a chosen residue set: real_part = (0, n) takes every n-th file
    (held out), (1, n) all the others (training)."""
    frames = [procedural_background(s) for s in procedural_seeds]
    names = [f"procedural:{s}" for s in procedural_seeds]
    folder = Path(real_dir).expanduser() if real_dir else None
    if folder is not None and folder.is_dir():
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
        held_out, every = real_part[0] == 0, int(real_part[1])
        for i, path in enumerate(files):
            if (i % every == 0) == held_out:
                frames.append(load_background(path))
                names.append(f"real:{path.name}")
    elif folder is not None:
        log.warning("real DIGIT backgrounds %s not found: procedural backgrounds only", folder)
    return np.stack(frames), names
