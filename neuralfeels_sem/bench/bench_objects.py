"""Object library: generation time and size of each shipped object, custom-loader speed."""

from __future__ import annotations

import time

import numpy as np

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects import disk_cache
from neuralfeels_sem.objects.custom import load_custom_object
from neuralfeels_sem.objects.example_files import EXAMPLES_DIR
from neuralfeels_sem.objects.library import build_arrays, make_object
from neuralfeels_sem.objects.procedural import RECIPES
from neuralfeels_sem.utils.paths import SHARED_DATA_DIR

CLASSES = tuple(DEFAULT_MATERIALS)


def _timed(fn, *args, **kwargs) -> tuple[object, float]:
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def run() -> dict:
    result: dict = {}
    for name in RECIPES:
        # No cache: the cost of a first run after the generating code changed.
        (_, faces, _, _), seconds = _timed(build_arrays, name)
        result[f"{name}_generate_s"] = round(seconds, 3)
        result[f"{name}_faces"] = len(faces)
    make_object("plushie", CLASSES)
    _, seconds = _timed(make_object, "plushie", CLASSES)
    result["make_object_in_process_cache_s"] = round(seconds, 4)
    path = disk_cache.entry_path("plushie")
    if path.is_file():
        _, seconds = _timed(disk_cache.load, path, ("vertices", "faces", "names"))
        result["disk_cache_load_s"] = round(seconds, 4)
    _, seconds = _timed(load_custom_object, str(EXAMPLES_DIR / "two_tone_egg.obj"), CLASSES)
    result["custom_example_load_s"] = round(seconds, 3)
    ycb = SHARED_DATA_DIR / "ycb" / "MustardBottle" / "model.obj"
    if ycb.is_file():
        _, seconds = _timed(
            load_custom_object, str(ycb), CLASSES, material="metal", rescale_to=0.08
        )
        result["custom_ycb_load_s"] = round(seconds, 3)
    obj = make_object("patched_toy", CLASSES)
    points, _, _ = obj.sample_surface(20_000, seed=0)
    _, seconds = _timed(
        obj.labels_at, points + 0.001 * np.random.default_rng(0).normal(size=points.shape)
    )
    result["labels_at_points_per_s"] = round(len(points) / seconds)
    return result
