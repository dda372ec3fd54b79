"""The uncertainty section of the results page: how well the material branch's entropy
points at the map's errors (`metrics.json["uncertainty"]`, eval/uncertainty.py).

A row per source and object, over the offline runs that recorded the figures: mean-class
matching beside the majority map, the share of scored samples the map gets wrong, the
AUROC of entropy as a detector of those errors, the calibration error and the mean
entropy on right and on wrong samples (means ± std over runs).
"""

from __future__ import annotations

from collections.abc import Sequence

from neuralfeels_sem.eval.results_runs import Run, Source, get
from neuralfeels_sem.eval.results_tables import majority_cells, mean_std, table, values_of

FIGURES = (
    ("uncertainty.error_share", 100.0, 1),
    ("uncertainty.auroc", 1.0, 2),
    ("uncertainty.ece", 1.0, 3),
)
HEADER = [
    "source",
    "object",
    "runs",
    "mean-class %",
    "majority map % (material)",
    "samples wrong %",
    "`auroc`",
    "`ece`",
    "mean entropy right / wrong",
]


def uncertainty_rows(source: Source, runs: Sequence[Run]) -> list[list[str]]:
    groups: dict[str, list[Run]] = {}
    for run in runs:
        if get(run.metrics, "uncertainty.auroc") is not None:
            groups.setdefault(run.object, []).append(run)
    rows = []
    for obj, members in groups.items():
        floor, _ = majority_cells(members)
        entropy = " / ".join(
            mean_std(values_of(members, f"uncertainty.mean_entropy_{kind}"), 2)
            for kind in ("correct", "wrong")
        )
        rows.append(
            [
                f"`{source.label}`",
                f"`{obj}`",
                str(len(members)),
                mean_std(values_of(members, "matching_mean_class_pct")),
                floor,
                *(
                    mean_std(values_of(members, key, scale), digits)
                    for key, scale, digits in FIGURES
                ),
                entropy,
            ]
        )
    return rows


INTRO = [
    "How well the material branch's normalised entropy marks where the map is wrong (see",
    "[evaluation](evaluation.md#uncertainty-of-the-material-map)): `auroc` of entropy as a",
    "detector of wrong samples (0.5: no better than chance), `ece` the calibration error of",
    "the map's confidence, and the mean entropy on right and on wrong samples. Mean ± std",
    "over the offline runs of each source and object that recorded the figures (runs of the",
    "pose-tracking and active-touch sections left out).",
]


def uncertainty_section(sources: Sequence[Source], table_runs: Sequence[Run]) -> list[str]:
    """`table_runs`: the runs of the object and settings tables (no section of their own)."""
    kept = {id(r) for r in table_runs if r.metrics.get("pace") != "realtime"}
    rows = []
    for source in sources:
        rows += uncertainty_rows(source, [r for r in source.runs if id(r) in kept])
    if not rows:
        return []
    return ["", "## Uncertainty of the material map", "", *INTRO, "", *table(HEADER, rows)]
