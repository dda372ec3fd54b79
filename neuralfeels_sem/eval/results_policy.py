"""The active-touch section of the results page: `sensor.policy=scripted` against `active`.

One table per source that holds `sensor.policy` runs, a row per object and seed: the
majority map, then for each policy the final mean-class matching and the time (sensor
seconds) at which the run's mean-class curve first reached TARGET_PCT, and the active
run's gain. The scripted partner is the run with `sensor.policy=scripted` in the same
source (same code, run side by side); where the source has none, the scripted run of the
same object, seed, oracles and other settings among the page's sources stands in, marked
with a dagger.
"""

from __future__ import annotations

from collections.abc import Sequence

from neuralfeels_sem.eval.results_runs import Run, Source, get, reference_run
from neuralfeels_sem.eval.results_tables import (
    fmt,
    majority_cells,
    mean,
    oracles_cell,
    setting_label,
    table,
    values_of,
)

POLICY_KEY = "sensor.policy"
TARGET_PCT = 90.0  # mean-class matching whose first crossing times the policies
STAND_IN = "†"


def is_policy_run(run: Run) -> bool:
    return POLICY_KEY in run.overrides  # scripted, today's default, is not a setting


def time_to_target(run: Run) -> float | None:
    """Sensor time of the first scoring pass at or above TARGET_PCT; None when never."""
    curve = get(run.metrics, "matching_mean_class_curve")
    if not isinstance(curve, list):
        return None
    for point in curve:
        if isinstance(point, list) and len(point) == 3 and point[2] >= TARGET_PCT:
            return float(point[1])
    return None


def coverage_pct(run: Run) -> float | None:
    """Share of the run's touches that got a label (the classifier's coverage), in %."""
    share = get(run.metrics, "classifier_accuracy.coverage")
    return None if share is None else 100.0 * share


def policy_cells(run: Run | None, mark: str = "") -> list[str]:
    if run is None:
        return ["n/a", "n/a", "n/a"]
    final = fmt(get(run.metrics, "matching_mean_class_pct")) + mark
    t90 = time_to_target(run)
    return [final, "-" if t90 is None else f"{t90:.1f} s", fmt(coverage_pct(run))]


def regrasps(run: Run | None) -> int | None:
    """Regrasps the active run made (`touch_plan.regrasps` of its touch_suggestions.json)."""
    if run is None or run.touch_plan is None:
        return None
    found = run.touch_plan.get("regrasps")
    return len(found) if isinstance(found, list) else None


def pairs(runs: Sequence[Run], candidates: Sequence[Run], varying: Sequence[str]) -> list[tuple]:
    """(label, seed, scripted run or None, stand-in flag, active run or None) per row."""
    rows: dict[tuple, dict] = {}
    for run in runs:
        key = (setting_label(run, varying), run.seed, oracles_cell(run))
        rows.setdefault(key, {})[run.overrides[POLICY_KEY]] = run
    out = []
    for (label, seed, _), found in rows.items():
        scripted, active = found.get("scripted"), found.get("active")
        stand_in = scripted is None and active is not None
        if stand_in:
            scripted = reference_run(active, candidates, varied=POLICY_KEY)
        out.append((label, seed, scripted, stand_in and scripted is not None, active))
    return sorted(out, key=lambda p: (p[0], p[1] is None, p[1] or 0))


def gain(scripted: Run | None, active: Run | None) -> float | None:
    """Active minus scripted final mean-class matching, in points."""
    if scripted is None or active is None:
        return None
    before, after = (get(r.metrics, "matching_mean_class_pct") for r in (scripted, active))
    return after - before if before is not None and after is not None else None


def mean_row(label: str, rows: Sequence[tuple]) -> list[str]:
    """Means over the seeds where both policies ran, and how often each reached the target;
    where no seed has both (a sweep of one policy), each policy's means over its own runs."""
    both = [(s, a) for _, _, s, _, a in rows if s is not None and a is not None]
    scripted, active = [s for s, _ in both], [a for _, a in both]
    if not both:
        scripted = [s for _, _, s, _, _ in rows if s is not None]
        active = [a for *_, a in rows if a is not None]
    reached = [sum(time_to_target(r) is not None for r in runs) for runs in (scripted, active)]
    floor, _ = majority_cells(active or scripted)
    return [
        label,
        "**mean**",
        floor,
        fmt(mean(values_of(scripted, "matching_mean_class_pct"))),
        reached_cell(reached[0], len(scripted)),
        fmt(mean([c for r in scripted if (c := coverage_pct(r)) is not None])),
        fmt(mean(values_of(active, "matching_mean_class_pct"))),
        reached_cell(reached[1], len(active)),
        fmt(mean([c for r in active if (c := coverage_pct(r)) is not None])),
        fmt(mean([g for s, a in both if (g := gain(s, a)) is not None]), sign=True),
        count_cell([regrasps(a) for a in active]),
    ]


def reached_cell(reached: int, runs: int) -> str:
    """How many of a policy's runs reached the target (n/a: that policy did not run)."""
    return f"{reached} of {runs} reached" if runs else "n/a"


def count_cell(counts: Sequence[int | None]) -> str:
    known = [c for c in counts if c is not None]
    return str(sum(known)) if known else "n/a"


HEADER = [
    "setting",
    "seed",
    "majority map % (material)",
    "scripted: mean-class %",
    f"scripted: time to {TARGET_PCT:.0f} %",
    "scripted: touches labelled %",
    "active: mean-class %",
    f"active: time to {TARGET_PCT:.0f} %",
    "active: touches labelled %",
    "active - scripted",
    "active: regrasps",
]


def policy_table(source: Source, runs: Sequence[Run], candidates: Sequence[Run]) -> list[str]:
    keys = sorted({k for r in runs for k in r.setting if k != POLICY_KEY})
    varying = [k for k in keys if len({r.setting.get(k) for r in runs}) > 1]
    constant = [k for k in keys if k not in varying]
    rows, found = [], pairs(runs, candidates, varying)
    for label in dict.fromkeys(p[0] for p in found):
        members = [p for p in found if p[0] == label]
        for _, seed, scripted, stand_in, active in members:
            floor, _ = majority_cells([r for r in (active, scripted) if r is not None])
            rows.append(
                [label, str(seed), floor]
                + policy_cells(scripted, STAND_IN if stand_in else "")
                + policy_cells(active)
                + [fmt(gain(scripted, active), sign=True), count_cell([regrasps(active)])]
            )
        if len(members) > 1:
            rows.append(mean_row(label, members))
    lines = [f"### `{source.label}`", ""]
    if constant:
        fixed = ", ".join(f"`{k}={runs[0].setting[k]}`" for k in constant)
        lines += [f"Every run here: {fixed}.", ""]
    if any(p[3] for p in found):
        lines += [
            f"{STAND_IN} no scripted run in this source: the scripted run of the same object,",
            "seed, oracles and other settings from another source of this page.",
            "",
        ]
    return lines + table(HEADER, rows)


INTRO = [
    "Where each new touch goes: `sensor.policy=scripted` (the gait's own contact sampling)",
    "or `active` (the touch the map is least sure of and least touched near; see",
    "[simulation](simulation.md#active-touch-sensorpolicyactive)). Per object and seed:",
    "the final mean-class matching of each policy beside the majority map, and the sensor",
    f"time at which its mean-class curve first reached {TARGET_PCT:.0f} % (- where it never did",
    "in the run), the share of its touches the classifier labelled (the rest abstained),",
    "and the regrasps the active run made (`touch_plan.regrasps` in its",
    "`touch_suggestions.json`, chosen turns among them; n/a where the file is absent).",
    "The mean rows pool the seeds where both policies ran (in a sweep of one policy, its",
    "own runs).",
]


def policy_section(sources: Sequence[Source], candidates: Sequence[Run]) -> list[str]:
    lines: list[str] = []
    for source in sources:
        members = [r for r in source.runs if is_policy_run(r)]
        if members:
            lines += policy_table(source, members, candidates) + [""]
    if not lines:
        return []
    return ["", "## Active touch", "", *INTRO, "", *lines[:-1]]
