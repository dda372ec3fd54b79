"""The speed section of the results page, read from a `make bench` report (bench.json).

Only the figures named in FIGURES are shown, in that order; a figure the report does not
hold (an older report, a benchmark that failed or did not run on this machine) is left out,
never filled in. Each benchmark's own load average is shown where it recorded one, since
these machines are shared and a figure means little without it.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

from neuralfeels_sem.core.errors import DataError

# (benchmark, dotted key inside its result, what it measures, unit)
FIGURES: tuple[tuple[str, str, str, str], ...] = (
    ("sim", "full_frames_per_s", "simulated rig, 4 DIGITs + RGB-D", "frames/s"),
    ("sim", "sim_steps_per_s", "MuJoCo steps", "steps/s"),
    ("sim", "rig_updates_per_s", "rig updates (policy + IK + press control)", "updates/s"),
    ("sim", "tactile_frames_per_s", "DIGIT renders", "img/s"),
    ("sim", "tactile_4_fingers_per_s", "four-finger DIGIT sets", "sets/s"),
    ("sim", "camera_frames_per_s", "camera renders", "frames/s"),
    ("sim", "mean_fingers_touching", "fingers touching on average", "fingers"),
    ("render", "tactile_ms_in_contact", "DIGIT render in contact", "ms"),
    ("render", "tactile_ms_no_contact", "DIGIT render, no contact", "ms"),
    ("render", "tactile_ms_lifted_2cm", "DIGIT render, lifted 2 cm (no GL pass)", "ms"),
    ("render", "camera_ms", "camera render", "ms"),
    ("segmentation", "plushie.mask_iou_mean", "camera segmentation IoU (plushie, mean)", ""),
    ("segmentation", "plushie.mask_iou_min", "camera segmentation IoU (plushie, worst)", ""),
    ("segmentation", "patched_toy.mask_iou_mean", "camera segmentation IoU (patched_toy)", ""),
    (
        "segmentation",
        "patched_toy.mask_iou_min",
        "camera segmentation IoU (patched_toy, worst)",
        "",
    ),
    ("segmentation", "plushie.segmentation_ms", "camera segmentation (plushie)", "ms/frame"),
    ("segmentation", "camera_frames_per_s.bare", "camera, object and hand only", "frames/s"),
    ("segmentation", "camera_frames_per_s.lab_scenery", "camera with the lab scenery", "frames/s"),
    (
        "segmentation",
        "camera_frames_per_s.lab_scenery_realsense",
        "camera with scenery and RealSense noise",
        "frames/s",
    ),
    ("tactile_depth", "images_per_s_cpu_1thread", "tactile depth net, batch 4, 1 thread", "img/s"),
    ("tactile_depth", "images_per_s_cpu_2thread", "tactile depth net, batch 4, 2 threads", "img/s"),
    (
        "tactile_depth",
        "images_per_s_cpu_torch_1thread",
        "tactile depth net, batch 4, 1 thread, torch",
        "img/s",
    ),
    (
        "classifier",
        "images_per_s_shipped_112px_cpu",
        "classifier, shipped 112 px, batch 4",
        "img/s",
    ),
    (
        "classifier",
        "images_per_s_shipped_112px_cpu_1thread",
        "classifier, shipped 112 px, batch 4, 1 thread",
        "img/s",
    ),
    (
        "classifier",
        "images_per_s_shipped_112px_cpu_torch",
        "classifier, shipped 112 px, batch 4, torch",
        "img/s",
    ),
    ("classifier", "images_per_s_224px_cpu", "classifier, paper's 224 px, batch 4", "img/s"),
    ("classifier", "contact_gate_ms_per_frame", "contact gate", "ms/frame"),
    (
        "field",
        "cpu_cpu_default_log2_16_sparse.steps_per_s",
        "field step, 4096 points, 2^16",
        "steps/s",
    ),
    (
        "field",
        "cpu_cpu_default_log2_16_dense.steps_per_s",
        "field step, 4096 points, 2^16, dense Adam",
        "steps/s",
    ),
    # 2^19: the CPU default of reports made before 2^16 was, and a larger table since.
    (
        "field",
        "cpu_cpu_default_log2_19_sparse.steps_per_s",
        "field step, 4096 points, 2^19",
        "steps/s",
    ),
    ("field", "cpu_larger_log2_19_sparse.steps_per_s", "field step, 4096 points, 2^19", "steps/s"),
    (
        "field",
        "cpu_cpu_default_log2_19_dense.steps_per_s",
        "field step, 4096 points, 2^19, dense Adam",
        "steps/s",
    ),
    (
        "field",
        "cpu_larger_log2_19_dense.steps_per_s",
        "field step, 4096 points, 2^19, dense Adam",
        "steps/s",
    ),
    ("field", "cpu_paper_log2_24_sparse.steps_per_s", "field step, 4096 points, 2^24", "steps/s"),
    (
        "field",
        "cpu_paper_log2_24_dense.steps_per_s",
        "field step, 4096 points, 2^24, dense Adam",
        "steps/s",
    ),
    (
        "field",
        "cpu_paper_log2_24_sparse.peak_rss_delta_mb_with_query",
        "peak memory added, 2^24 step and SDF query",
        "MB",
    ),
    (
        "field",
        "cuda_cpu_default_log2_19_sparse.steps_per_s",
        "field step on the GPU, 4096 points, 2^19",
        "steps/s",
    ),
    (
        "field",
        "cuda_cpu_default_log2_16_sparse.steps_per_s",
        "field step on the GPU, 4096 points, 2^16",
        "steps/s",
    ),
    (
        "field",
        "cuda_paper_log2_24_sparse.steps_per_s",
        "field step on the GPU, 4096 points, 2^24",
        "steps/s",
    ),
    ("field", "cuda_paper_log2_24_sparse.peak_gpu_mb", "GPU memory, 2^24 step", "MB"),
    ("mapper", "steps_per_s", "mapper step (default config)", "steps/s"),
    ("label_vote", "vote_ms_at_1000", "label vote over 1000 touch readings", "ms"),
    ("label_vote", "vote_ms_at_3000", "label vote over 3000 touch readings", "ms"),
    ("mapper", "steps_per_s_by_threads.1.steps_per_s", "mapper step, 1 thread", "steps/s"),
    ("mapper", "steps_per_s_by_threads.2.steps_per_s", "mapper step, 2 threads", "steps/s"),
    ("mapper", "steps_per_s_by_threads.1.step_cpu_ms", "mapper step CPU, 1 thread", "ms"),
    ("mapper", "steps_per_s_by_threads.2.step_cpu_ms", "mapper step CPU, 2 threads", "ms"),
    (
        "mapper",
        "default_run.realtime_factor",
        "default run: sensor time / loop time (median of the repeats)",
        "x",
    ),
    ("mapper", "default_run.realtime_factor_min", "default run: lowest of the repeats", "x"),
    ("mapper", "default_run.realtime_factor_max", "default run: highest of the repeats", "x"),
    ("mapper", "default_run.producer_busy", "default run: producer thread busy (of the loop)", "x"),
    ("mapper", "default_run.mapper_busy", "default run: mapper thread busy (of the loop)", "x"),
    ("mapper", "default_run.matching_mean_class_pct", "default run: mean-class matching", "%"),
    (
        "mapper",
        "default_run.baseline_majority_mean_class_pct",
        "default run: majority map, mean-class",
        "%",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24.realtime_factor",
        "default run on the GPU, 2^24 table: sensor time / loop time",
        "x",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24.matching_mean_class_pct",
        "default run on the GPU, 2^24 table: mean-class matching",
        "%",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24.producer_busy",
        "default run on the GPU, 2^24 table: producer thread busy",
        "x",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24_acquire.realtime_factor",
        "the same, acquisition in a thread of its own: sensor time / loop time",
        "x",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24_one_thread.realtime_factor",
        "the same, one producer thread: sensor time / loop time",
        "x",
    ),
    (
        "mapper",
        "default_run_cuda_log2_24_sim_inline.realtime_factor",
        "the same, the simulator in the mapping process: sensor time / loop time",
        "x",
    ),
    ("mapper", "frame_points_ms", "mapper frame points (perception)", "ms/frame"),
    ("mapper", "add_frame_per_s", "mapper frames (points + steps)", "frames/s"),
    ("pose", "known_shape.ms_per_frame", "pose tracking against the true shape", "ms/frame"),
    ("pose", "field.ms_per_frame", "pose tracking against the field", "ms/frame"),
    (
        "pose",
        "colour.with_colour_ms_per_frame",
        "pose tracking against the field with colour rows (painted sphere)",
        "ms/frame",
    ),
    ("pose", "window.ms_per_refinement", "pose window: one joint refinement of 4 frames", "ms"),
    ("pose", "grid_96_build_s", "true-shape SDF grid (96^3) build", "s"),
    ("checkpoint", "size_mb", "checkpoint of the default config", "MB"),
    ("checkpoint", "exact_size_mb", "checkpoint, exact storage", "MB"),
    ("checkpoint", "unpacked_size_mb", "checkpoint state stored whole", "MB"),
    ("checkpoint", "updated_row_fraction", "share of table rows updated", ""),
    ("checkpoint", "save_s", "checkpoint save", "s"),
    ("checkpoint", "load_s", "checkpoint load", "s"),
    ("recording", "write_fps", "recording written", "frames/s"),
    ("recording", "read_fps", "recording replayed", "frames/s"),
    ("recording", "feelsight_export_fps", "recording exported to FeelSight", "frames/s"),
    ("recording", "disk_mb_per_frame", "recording on disk", "MB/frame"),
    ("objects", "plushie_generate_s", "object generation (plushie, no cache)", "s"),
    ("objects", "disk_cache_load_s", "object from the disk cache", "s"),
    ("objects", "custom_example_load_s", "custom mesh, shipped example", "s"),
    ("objects", "custom_ycb_load_s", "custom mesh, YCB scan", "s"),
    ("objects", "labels_at_points_per_s", "material labels at points", "points/s"),
    ("eval", "shape_metrics_s", "F-score + Chamfer, 20,000 samples", "s"),
)
LOAD_KEYS = ("load_average_1min", "load_avg_1min", "load_average_1min_1thread")


def load_bench(path: Path) -> dict:
    """A bench.json report; a missing or malformed file is one DataError line."""
    try:
        report = json.loads(path.read_text())
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror}); run `make bench` first") from None
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}: not a bench report ({exc.msg}); run `make bench` again") from None
    if not isinstance(report, dict) or not isinstance(report.get("results"), dict):
        raise DataError(f"{path}: no 'results' object; run `make bench` again")
    return report


def lookup(result: dict, dotted: str):
    value = result
    for key in dotted.split("."):
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value if isinstance(value, int | float) and not isinstance(value, bool) else None


def bench_load(result: dict) -> str:
    for key in LOAD_KEYS:
        if isinstance(result.get(key), int | float):
            return f"{result[key]:.1f}"
    return "-"


def bench_lines(report: dict, source: str) -> list[str]:
    """The speed table and a line naming the report, its date and machine."""
    results = report["results"]
    rows = []
    for bench, key, what, unit in FIGURES:
        result = results.get(bench)
        value = lookup(result, key) if isinstance(result, dict) else None
        if value is not None:
            figure = f"{value:g} {unit}".strip()
            rows.append(f"| {what} | {figure} | {bench_load(result)} | `{bench}.{key}` |")
    machine = report.get("machine", {})
    where = ", ".join(
        f"{k} {machine[k]}" for k in ("cpu_count", "cuda_device") if machine.get(k) is not None
    )
    # A report made by part of the bench says so in `ran`; a whole `make bench` has none.
    ran = report.get("ran", "`make bench`")
    head = [
        f"From `{source}` ({ran}, started {report.get('started', 'unknown')}; {where or 'machine not recorded'}).",
        "",
    ]
    if not rows:
        return head + ["The report holds none of the figures this page shows."]
    return head + [
        "| what | figure | 1-min load | bench.json key |",
        "| --- | ---: | ---: | --- |",
        *rows,
    ]


def speed_section(
    benches: Sequence[Path], locate: Callable[[Path], Path] = lambda path: path
) -> Sequence[str]:
    """One speed table per report: each machine's figures apart, with what it was
    (`locate`: where to read the report each path names)."""
    if not benches:
        return []
    intro = [
        "Speed, and the other figures the benchmarks measure on the way (segmentation IoU,",
        "checkpoint and recording sizes).",
        "",
    ]
    tables = []
    for bench in benches:
        tables += [*bench_lines(load_bench(locate(bench)), bench.as_posix()), ""]
    return ["", "## Speed", "", *intro, *tables[:-1]]
