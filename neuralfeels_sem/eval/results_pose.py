"""The pose-tracking section of the results page: runs with `mapping.pose` other than `gt`.

One table per source, a row per run: the pose error (mean, maximum and final, mm), frames
not tracked, retried and re-localised, tracking time per frame with the run's own load (the machines are
shared, so a time means little without it), and the run's mean-class matching and F-score
beside those of the `pose=gt` run of the same object and seed among the default-config
runs of the page (the run a user with the true pose would get).
"""

from __future__ import annotations

from collections.abc import Sequence

from neuralfeels_sem.eval.results_drift import unread_beside
from neuralfeels_sem.eval.results_runs import Run, Source, reference_run
from neuralfeels_sem.eval.results_tables import (
    by_seed,
    fmt,
    majority_cells,
    mean,
    setting_label,
    table,
    values_of,
)

POSE_KEY = "mapping.pose"


def is_tracked(run: Run) -> bool:
    """The run estimated the object pose instead of reading the simulator's."""
    return run.setting.get(POSE_KEY, "gt") != "gt"


def pose_runs(source: Source) -> tuple[list[Run], list[Run]]:
    """(tracked runs, the source's own `mapping.pose=gt` runs); the second are the tracked
    runs' partners (same sweep, same code) and go with them, but only where there are any."""
    tracked = [r for r in source.runs if is_tracked(r)]
    partners = [r for r in source.runs if r.overrides.get(POSE_KEY) == "gt"] if tracked else []
    return tracked, partners


def partner_of(run: Run, partners: Sequence[Run], candidates: Sequence[Run]) -> Run | None:
    """The `pose=gt` run to compare with: the source's run with the same other settings,
    object and seed, else the run of the same object, seed and other settings among the
    page's runs (its `mapping.pose` at today's default); tracker settings do not count."""
    unread = unread_beside(POSE_KEY)
    rest = {k: v for k, v in run.setting.items() if k != POSE_KEY and not k.startswith(unread)}
    for other in partners:
        same = {k: v for k, v in other.setting.items() if k != POSE_KEY} == rest
        if same and other.object == run.object and other.seed == run.seed:
            return other
    return reference_run(run, candidates, dropped=("object_pose",), varied=POSE_KEY)


def load_of(run: Run) -> float | None:
    """The 1-minute load average the run recorded at its end."""
    load = run.metrics.get("load_avg")
    if isinstance(load, list | tuple) and load:
        load = load[0]
    return float(load) if isinstance(load, int | float) else None


def time_with_load(seconds: float | None, load: float | None) -> str:
    if seconds is None:
        return "n/a"
    return f"{seconds:.2f} ({fmt(load, 0)})" if load is not None else f"{seconds:.2f}"


def error_cell(runs: Sequence[Run]) -> str:
    keys = ("pose_error_mm", "pose_error_max_mm", "pose_error_final_mm")
    return " / ".join(fmt(mean(values_of(runs, key)), 2) for key in keys)


def closest_cell(runs: Sequence[Run]) -> str:
    keys = ("pose_error_closest_mm", "pose_error_closest_final_mm")
    return " / ".join(fmt(mean(values_of(runs, key)), 2) for key in keys)


def untracked_cell(runs: Sequence[Run]) -> str:
    keys = ("pose_frames_not_tracked", "pose_frames_reinitialised", "pose_frames_relocalised")
    return " / ".join(
        fmt(sum(values_of(runs, key)), 0) if values_of(runs, key) else "n/a" for key in keys
    )


def pose_row(label: str, seed: str, runs: Sequence[Run], references: Sequence[Run]) -> list[str]:
    floor, _ = majority_cells(runs)
    seconds = mean(values_of(runs, "pose_track_s_per_frame"))
    loads = [x for r in runs if (x := load_of(r)) is not None]
    return [
        label,
        seed,
        error_cell(runs),
        closest_cell(runs),
        untracked_cell(runs),
        time_with_load(seconds, mean(loads) if loads else None),
        fmt(mean(values_of(runs, "matching_mean_class_pct"))),
        floor,
        fmt(mean(values_of(references, "matching_mean_class_pct"))),
        fmt(mean(values_of(runs, "fscore_5mm")), 3),
        fmt(mean(values_of(references, "fscore_5mm")), 3),
    ]


HEADER = [
    "setting",
    "seed",
    "pose error mean / max / final mm",
    "closest-point error mean / final mm",
    "frames not tracked / retried / re-localised",
    "tracking s/frame (1-min load)",
    "mean-class %",
    "majority map % (material)",
    "`pose=gt` mean-class %",
    "F-score @5 mm",
    "`pose=gt` F-score",
]


def pose_table(
    source: Source, runs: Sequence[Run], partners: Sequence[Run], candidates: Sequence[Run]
) -> list[str]:
    """A row per run, then a row per setting with the means over its seeds."""
    keys = sorted({k for r in runs for k in r.setting})
    varying = [k for k in keys if len({r.setting.get(k) for r in runs}) > 1]
    constant = [k for k in keys if k not in varying]
    groups: dict[str, list[Run]] = {}
    for run in runs:
        groups.setdefault(setting_label(run, varying), []).append(run)
    rows = []
    for label, members in groups.items():
        refs = {id(r): partner_of(r, partners, candidates) for r in members}
        for run in by_seed(members):
            ref = refs[id(run)]
            rows.append(pose_row(label, str(run.seed), [run], [ref] if ref else []))
        if len(members) > 1:
            found = [r for r in refs.values() if r is not None]
            rows.append(pose_row(label, "**mean**", members, found))
    lines = [f"### `{source.label}`", ""]
    if constant:
        fixed = ", ".join(f"`{k}={runs[0].setting[k]}`" for k in constant)
        lines += [f"Every run here: {fixed}.", ""]
    return lines + table(HEADER, rows)


INTRO = [
    "Runs that estimated the object pose (`mapping.pose=track`: against the field being",
    "learned; `track_known_shape`: against the true mesh) instead of reading the simulator's",
    "(see [pose](pose.md)). Pose error: the mean distance between ground-truth surface",
    "samples placed by the tracked and by the true pose, averaged over frames, its maximum",
    "and its last value. The closest-point error measures each sample's distance to the",
    "nearest true surface sample instead: blind to motions a symmetric shape does not show",
    "(a body of revolution spinning about its axis), which the pose error counts.",
    "A `pose=gt` column is the run of the same object, seed and other",
    "settings with `mapping.pose=gt` in the same source, else the run of the object, seed and",
    "other settings among the sources of this page (n/a where there is none); the `pose=gt`",
    "runs of a source go with its tracked runs here. Tracking time per frame",
    "scales with the load of the shared machine, so it compares only roughly.",
]


def pose_section(sources: Sequence[Source], candidates: Sequence[Run]) -> list[str]:
    lines: list[str] = []
    for source in sources:
        tracked, partners = pose_runs(source)
        if tracked:
            lines += pose_table(source, tracked, partners, candidates) + [""]
    if not lines:
        return []
    return ["", "## Pose tracking", "", *INTRO, "", *lines[:-1]]
