"""The scanned-meshes section of the results page: custom meshes with drawn layouts.

Runs of `object=custom object.layout_seed=K` (experiment=scanned_objects: real scanned
shapes, each with generated material layouts): per setting, pooled over the sources (a
sweep per mapping seed), a row per mesh and layout with the same figures as the generated
objects' tables, then the mean over the layouts, how many reach TARGET_PCT and the lowest.
"""

from __future__ import annotations

from collections.abc import Sequence

from neuralfeels_sem.eval import results_tables as T
from neuralfeels_sem.eval.results_generated import (
    FIGURE_HEADER,
    FIGURES,
    FLOOR,
    MEAN_CLASS,
    TARGET_PCT,
    missed_runs_cell,
    never_read_cell,
)
from neuralfeels_sem.eval.results_pose import is_tracked
from neuralfeels_sem.eval.results_runs import OBJECT_LAYOUT, Run, Source, get

HEADER = [
    "mesh",
    "size",
    "layout seed",
    "materials: regions",
    "runs",
    "mean-class %",
    "majority map % (material)",
    *FIGURE_HEADER,
    "never read rightly",
]


def is_scanned(run: Run) -> bool:
    return get(run.metrics, OBJECT_LAYOUT) is not None


def scanned_references(runs: Sequence[Run]) -> list[Run]:
    """Runs on scanned meshes that read the simulator's pose: this section's tables, and
    the partners active-touch runs on the same layouts are compared with."""
    return [r for r in runs if is_scanned(r) and not is_tracked(r)]


def layout_key(run: Run) -> tuple[str, int]:
    made = get(run.metrics, OBJECT_LAYOUT)
    return str(made["mesh"]), int(made["layout_seed"])


def setting_text(run: Run) -> str:
    """The run's setting less the mesh and layout ("today's defaults" when that is all)."""
    rest = {k: v for k, v in run.setting.items() if not k.startswith("object.")}
    setting = ", ".join(f"`{k}={v}`" for k, v in sorted(rest.items())) or "today's defaults"
    return f"{setting} (oracles: {T.oracles_cell(run)})"


def layout_rows(runs: Sequence[Run]) -> tuple[list[list[str]], dict[tuple[str, int], float]]:
    """A row per (mesh, layout seed), and each one's mean-class matching."""
    groups: dict[tuple[str, int], list[Run]] = {}
    for run in sorted(runs, key=layout_key):
        groups.setdefault(layout_key(run), []).append(run)
    rows, per_layout = [], {}
    for (mesh, seed), members in groups.items():
        made = get(members[0].metrics, OBJECT_LAYOUT)
        regions = ", ".join(made.get("regions") or [])
        per_layout[(mesh, seed)] = T.mean(T.values_of(members, MEAN_CLASS))
        rows.append(
            [
                mesh,
                f"{T.fmt(100.0 * made['size_m'], 0)} cm" if made.get("size_m") else "?",
                str(seed),
                f"{len(made.get('materials') or [])}: {regions}",
                str(len(members)),
                T.fmt(per_layout[(mesh, seed)]),
                T.majority_cells(members)[0],
                *(T.fmt(T.mean(T.values_of(members, k, s)), d) for k, s, d in FIGURES),
                never_read_cell(members),
            ]
        )
    return rows, per_layout


def setting_table(runs: Sequence[Run]) -> list[str]:
    rows, per_layout = layout_rows(runs)
    scored = {k: v for k, v in per_layout.items() if v is not None}
    low = min(scored, key=scored.get) if scored else None
    reach = sum(v >= TARGET_PCT for v in scored.values())
    lowest = f"{T.fmt(scored[low])} ({low[0]}, layout {low[1]})" if low else "n/a"
    means = [
        f"**{T.mean_std(list(scored.values()))}**",
        T.fmt(T.mean(T.values_of(runs, FLOOR))),
        *(T.mean_std(T.values_of(runs, k, s), d) for k, s, d in FIGURES),
        missed_runs_cell(runs),
    ]
    return [
        f"Setting: {setting_text(runs[0])}. Mean-class matching at or above "
        f"{T.fmt(TARGET_PCT, 0)} %: {reach} of {len(scored)} layouts; lowest {lowest}.",
        "",
        *T.table(HEADER, rows + [["**mean**", "", "", "", str(len(runs)), *means]]),
    ]


INTRO = [
    "Runs on real scanned meshes (`object=custom`) with material layouts drawn onto them by",
    "`object.layout_seed=K` (the generated objects' kind of layout; see",
    "[objects](objects.md#your-own-mesh-objectcustom)): shapes and layouts no setting was",
    "tuned on, run to report. Per mesh and layout the same figures as for the generated",
    "objects, the materials some run's touches never read rightly among them; the mean is",
    "over layouts (the majority map's over runs).",
]


def scanned_section(sources: Sequence[Source]) -> list[str]:
    """One table per setting, its runs pooled over the sources (a mapping seed per sweep)."""
    settings: dict[str, list[tuple[str, Run]]] = {}
    for source in sources:
        for run in scanned_references(source.runs):
            settings.setdefault(setting_text(run), []).append((source.label, run))
    lines = []
    for members in settings.values():
        labels = ", ".join(f"`{label}`" for label in dict.fromkeys(lab for lab, _ in members))
        lines += [f"### {labels}", "", *setting_table([run for _, run in members]), ""]
    if not lines:
        return []
    return ["", "## Scanned meshes", "", *INTRO, "", *lines]
