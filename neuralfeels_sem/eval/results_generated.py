"""The generated-objects section of the results page: `object=random` runs, objects nobody tuned on.

Per setting, a row per generated object (its seed, shape family and material
regions): mean-class matching beside the majority map, the classifier's accuracy and
coverage, and the AUROC of the map's entropy against its errors; then the mean over the
objects, how many reach TARGET_PCT and the lowest. Evaluation runs of one setting are
pooled over the sweeps that ran it (a mapping seed each); a sweep that ran several settings
on the same objects also gets a comparison, on the objects every setting ran. Development
objects (seeds below EVALUATION_SEEDS_FROM) are pooled over every source, so
settings run in different sweeps are compared on the objects they all ran.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from neuralfeels_sem.eval.classifier_metrics import never_read
from neuralfeels_sem.eval.results_pose import is_tracked
from neuralfeels_sem.eval.results_runs import Run, Source, get
from neuralfeels_sem.eval.results_tables import (
    fmt,
    majority_cells,
    mean,
    mean_std,
    oracles_cell,
    table,
    values_of,
)
from neuralfeels_sem.objects.random_object import EVALUATION_SEEDS_FROM

TARGET_PCT = 80.0  # the per-object floor the unseen-objects benchmark asks for
GENERATION = "config.object_generation"  # what make_random_object built (metrics.json)
MEAN_CLASS = "matching_mean_class_pct"
FLOOR = "baseline_majority.matching_mean_class_pct"
FIGURES = (  # (metrics key, scale, digits) of the per-object columns after the majority map
    ("classifier_accuracy.overall", 100.0, 1),
    ("classifier_accuracy.coverage", 100.0, 1),
    ("uncertainty.auroc", 1.0, 2),
)
FIGURE_HEADER = ["classifier acc. %", "coverage %", "`auroc`"]


def is_generated(run: Run) -> bool:
    return get(run.metrics, GENERATION) is not None


def generated_references(runs: Sequence[Run]) -> list[Run]:
    """Runs on generated objects that read the simulator's pose: the tables of this
    section, and the partners that tracked runs (`pose=gt`) and active-touch runs
    (`sensor.policy=scripted`) are compared with in their own sections."""
    return [r for r in runs if is_generated(r) and not is_tracked(r)]


def object_seed(run: Run) -> int:
    return int(get(run.metrics, f"{GENERATION}.seed"))


def setting_rest(run: Run) -> dict:
    """The run's setting less the object's seed (empty: today's defaults)."""
    return {k: v for k, v in run.setting.items() if k != "object.seed"}


def setting_text(run: Run) -> str:
    """The run's setting less the object's seed ("today's defaults" when that is all) and
    the oracles it used."""
    rest = setting_rest(run)
    setting = ", ".join(f"`{k}={v}`" for k, v in sorted(rest.items())) or "today's defaults"
    return f"{setting} (oracles: {oracles_cell(run)})"


def by_setting(runs: Sequence[Run]) -> dict[str, list[Run]]:
    """{setting_text: its runs}, in the order the settings first come."""
    groups: dict[str, list[Run]] = {}
    for run in runs:
        groups.setdefault(setting_text(run), []).append(run)
    return groups


def by_object(runs: Sequence[Run]) -> dict[int, list[Run]]:
    groups: dict[int, list[Run]] = {}
    for run in sorted(runs, key=object_seed):
        groups.setdefault(object_seed(run), []).append(run)
    return groups


def object_means(
    runs: Sequence[Run], key: str = MEAN_CLASS, scale: float = 1.0
) -> dict[int, float]:
    """{object seed: mean of `key` over its runs} (objects without the figure left out)."""
    out = {}
    for seed, members in by_object(runs).items():
        values = values_of(members, key, scale)
        if values:
            out[seed] = mean(values)
    return out


def reach_cells(per_object: dict[int, float]) -> list[str]:
    """[objects at or above the target 'k of n', the lowest object 'x (seed s)']."""
    if not per_object:
        return ["n/a", "n/a"]
    low = min(per_object, key=per_object.get)
    at_target = sum(v >= TARGET_PCT for v in per_object.values())
    return [f"{at_target} of {len(per_object)}", f"{fmt(per_object[low])} (seed {low})"]


def describe(run: Run) -> list[str]:
    made = get(run.metrics, GENERATION)
    size = made.get("size_m")
    shape = f"{made.get('family', '?')}, {fmt(100.0 * size, 0)} cm" if size else "?"
    regions = ", ".join(made.get("regions") or [])
    return [shape, f"{len(made.get('materials') or [])}: {regions}"]


def mean_class_cell(runs: Sequence[Run]) -> str:
    """The runs' mean, and each run's figure after it when there are several
    ("74.3 (98.9, 49.7)"): a mean over mapping seeds hides a run that lost a part."""
    values = values_of(runs, MEAN_CLASS)
    if len(values) < 2:
        return fmt(mean(values))
    return f"{fmt(mean(values))} ({', '.join(fmt(v) for v in values)})"


def run_never_read(run: Run) -> dict[str, tuple[str, float]] | None:
    """{material: (why no touch read it rightly, the map's recall of it %)} for one run
    (classifier_metrics.never_read on its classifier tallies, so runs scored before
    metrics.json carried `materials_never_read` get it too); None: nothing to judge."""
    recall = get(run.metrics, "matching_per_class") or {}
    missed = never_read(get(run.metrics, "classifier_accuracy") or {}, list(recall))
    return None if missed is None else {k: (why, recall[k]) for k, why in missed.items()}


def never_read_cell(runs: Sequence[Run]) -> str:
    """The materials some run's touches never read rightly, with why, the run's mapping
    seed and the map's recall of the material in that run ("wood: never pressed (seed 1,
    map 0.0 %)"); "none" when every run's touches read every material, "-" when no run's
    touches had a ground truth."""
    verdicts = [(run, run_never_read(run)) for run in runs]
    parts = [
        f"{name}: {why} (seed {run.seed}, map {fmt(recall)} %)"
        for run, missed in verdicts
        for name, (why, recall) in (missed or {}).items()
    ]
    judged = any(missed is not None for _, missed in verdicts)
    return "; ".join(parts) or ("none" if judged else "-")


def missed_runs_cell(runs: Sequence[Run]) -> str:
    """How many of the runs that could be judged name a material in never_read_cell
    ("1 of 40 runs"); "-" when none could."""
    judged = [missed for missed in map(run_never_read, runs) if missed is not None]
    return f"{sum(bool(m) for m in judged)} of {len(judged)} runs" if judged else "-"


def object_rows(runs: Sequence[Run]) -> list[list[str]]:
    rows = []
    for seed, members in by_object(runs).items():
        floor, _ = majority_cells(members)
        rows.append(
            [
                str(seed),
                *describe(members[0]),
                str(len(members)),
                mean_class_cell(members),
                floor,
                *(fmt(mean(values_of(members, k, s)), d) for k, s, d in FIGURES),
                never_read_cell(members),
            ]
        )
    return rows


def over_objects(runs: Sequence[Run]) -> list[str]:
    """[mean-class, majority map, *FIGURES] as mean ± std over objects (each object's runs
    averaged first; the majority map as a plain mean)."""

    def values(key: str, scale: float = 1.0) -> list[float]:
        return list(object_means(runs, key, scale).values())

    return [
        f"**{mean_std(values(MEAN_CLASS))}**",
        fmt(mean(values(FLOOR))),
        *(mean_std(values(k, s), d) for k, s, d in FIGURES),
    ]


def summary_row(runs: Sequence[Run]) -> list[str]:
    mean_class, floor, *figures = over_objects(runs)
    return ["**mean**", "", "", str(len(runs)), mean_class, floor, *figures, missed_runs_cell(runs)]


OBJECT_HEADER = [
    "object seed",
    "shape",
    "materials: regions",
    "runs",
    "mean-class %",
    "majority map % (material)",
    *FIGURE_HEADER,
    "never read rightly",
]


def setting_table(runs: Sequence[Run]) -> list[str]:
    reach, lowest = reach_cells(object_means(runs))
    seeds = sorted(by_object(runs))
    kind = "evaluation" if seeds[0] >= EVALUATION_SEEDS_FROM else "development"
    if seeds[0] < EVALUATION_SEEDS_FROM <= seeds[-1]:
        kind = "development and evaluation"
    values = values_of(runs, MEAN_CLASS)
    per_run = ""
    if len(values) > len(seeds):  # several runs of an object: the target holds per run too
        per_run = f" Runs at or above: {sum(v >= TARGET_PCT for v in values)} of {len(values)}."
    return [
        f"Setting: {setting_text(runs[0])}; {kind} objects. Mean-class matching at or above "
        f"{fmt(TARGET_PCT, 0)} %: {reach} objects; lowest {lowest}.{per_run}",
        "",
        *table(OBJECT_HEADER, object_rows(runs) + [summary_row(runs)]),
    ]


COMPARISON_HEADER = [
    "setting",
    "mean-class % per object (seed order)",
    "mean-class % (mean ± std over objects)",
    "majority map %",
    f"objects >= {fmt(TARGET_PCT, 0)} %",
    "lowest",
    *FIGURE_HEADER,
]


def comparison_table(settings: dict[str, list[Run]]) -> list[str]:
    """One row per setting over the object seeds every setting ran (at least one)."""
    common = set.intersection(*(set(by_object(rs)) for rs in settings.values()))
    rows = []
    for label, runs in settings.items():
        kept = [r for r in runs if object_seed(r) in common]
        per_object = object_means(kept)
        mean_class, floor, *figures = over_objects(kept)
        rows.append(
            [
                label,
                ", ".join(fmt(per_object[s]) for s in sorted(per_object)),
                mean_class,
                floor,
                *reach_cells(per_object),
                *figures,
            ]
        )
    seeds = ", ".join(str(s) for s in sorted(common))
    return [
        f"Pooled on object seeds {seeds} (every setting ran them).",
        "",
        *table(COMPARISON_HEADER, rows),
    ]


def evaluation_tables(members: Sequence[tuple[str, Run]]) -> list[str]:
    """Evaluation runs (source label, run): one table per setting, its runs pooled over the
    sources that ran it (each sweep a mapping seed, run once to report)."""
    settings: dict[str, list[tuple[str, Run]]] = {}
    for label, run in members:
        settings.setdefault(setting_text(run), []).append((label, run))
    lines = []
    for pooled in settings.values():
        labels = ", ".join(f"`{label}`" for label in dict.fromkeys(lab for lab, _ in pooled))
        lines += [f"### {labels}", "", *setting_table([run for _, run in pooled]), ""]
    for label in dict.fromkeys(lab for lab, _ in members):  # one code version each
        own = by_setting([run for lab, run in members if lab == label])
        if len(own) > 1:
            lines += [f"### `{label}`: its settings compared", "", *comparison_table(own), ""]
    return lines


INTRO = [
    "Runs on objects generated by `object=random object.seed=K` (shape family, size and",
    "material layout drawn from the seed; see [objects](objects.md)): objects no setting was",
    f"tuned on. Seeds from {EVALUATION_SEEDS_FROM} are the evaluation set, run to report and",
    "never to choose settings; seeds below are for development. Per object: mean-class",
    "matching beside the majority map, the classifier's accuracy on judged touches and its",
    "coverage (share of touches given a label), and `auroc`, how well the map's entropy marks",
    "where it is wrong ([uncertainty](#uncertainty-of-the-material-map)); last, each material",
    "that no touch of some run read rightly by its label, and why (never pressed squarely by a",
    "finger, pressed but never labelled: the classifier abstained, or only read as another",
    "material), with the map's recall of it in that run: a press that reads a material on",
    "part of its imprint can still teach the map it, so read the two together.",
]


def comparisons_with_defaults(settings: dict[str, list[Run]]) -> list[str]:
    """One comparison per set of objects that settings share with today's defaults (the
    defaults and each setting that ran those objects), largest first; without a
    default-config run, one comparison over the objects every setting ran."""
    default = next((k for k, runs in settings.items() if not setting_rest(runs[0])), None)
    if default is None:
        return comparison_table(settings) + [""]
    default_seeds = set(by_object(settings[default]))
    groups: dict[frozenset[int], dict[str, list[Run]]] = {}
    for label, runs in settings.items():
        common = frozenset(default_seeds & set(by_object(runs)))
        if label != default and common:
            groups.setdefault(common, {default: settings[default]})[label] = runs
    lines = []
    for common in sorted(groups, key=lambda seeds: (-len(seeds), sorted(seeds))):
        lines += comparison_table(groups[common]) + [""]
    return lines


def development_tables(runs: Sequence[Run]) -> list[str]:
    """Every source's development runs together: the settings compared with today's
    defaults on the objects both ran, then the objects of today's defaults (when they
    ran)."""
    settings = by_setting(runs)
    lines = ["### Development objects, every source", ""]
    if len(settings) > 1:
        lines += comparisons_with_defaults(settings)
    default = [members for members in settings.values() if not setting_rest(members[0])]
    for members in default or list(settings.values())[:1]:
        lines += setting_table(members) + [""]
    return lines


def evaluation_runs_at_defaults(sources: Sequence[Source]) -> list[Run]:
    """Today's default-config runs on the evaluation objects, every source's pooled."""
    return [
        run
        for source in sources
        for run in generated_references(source.runs)
        if object_seed(run) >= EVALUATION_SEEDS_FROM and not setting_rest(run)
    ]


LOST_RECALL_PCT = 50.0  # a material the map recalls less than this counts as lost


def lost_materials_text(runs: Sequence[Run]) -> str:
    """What the runs below the target lost: 'Of the 3 runs below 80 %, 3 lost a material no
    touch read rightly (2 never pressed, 1 never labelled).', with a leading space (a
    material is lost when the map recalls under LOST_RECALL_PCT of it); empty when no run
    is below the target or none of those has touches to judge."""
    low = [r for r in runs if (get(r.metrics, MEAN_CLASS) or 0.0) < TARGET_PCT]
    judged = [missed for missed in map(run_never_read, low) if missed is not None]
    if not judged:
        return ""
    lost = [[why for why, recall in m.values() if recall < LOST_RECALL_PCT] for m in judged]
    lost_runs = sum(bool(whys) for whys in lost)
    reasons = [why for whys in lost for why in whys]
    counts = ", ".join(f"{n} {why}" for why, n in Counter(reasons).most_common())
    return (
        f" Of the {len(low)} runs below {fmt(TARGET_PCT, 0)} %, {lost_runs} lost a material no "
        f"touch read rightly{f' ({counts})' if counts else ''}."
    )


def evaluation_summary(runs: Sequence[Run]) -> str:
    """One sentence on the evaluation set at today's defaults (the README's, beside its
    table): mean-class over the objects (each object's runs averaged first) beside the
    majority map, the runs at TARGET_PCT and the lowest object."""
    per_object = object_means(runs)
    floor = mean(list(object_means(runs, FLOOR).values()))
    seeds = sorted({run.seed for run in runs if run.seed is not None})
    at_target = sum(v >= TARGET_PCT for v in values_of(runs, MEAN_CLASS))
    low = min(per_object, key=per_object.get)
    oracles = ", ".join(sorted({oracles_cell(run) for run in runs}))
    return (
        f"**Objects nobody tuned on**: the {len(per_object)} generated evaluation objects "
        f"(`experiment=unseen_objects`; {len(runs)} runs, mapping seeds "
        f"{', '.join(map(str, seeds)) or 'not recorded'}; oracles: {oracles}) map "
        f"**{fmt(mean(list(per_object.values())))} %** mean-class on average against "
        f"{fmt(floor)} % for the majority map; {at_target} of {len(runs)} runs at or above "
        f"{fmt(TARGET_PCT, 0)} %, the lowest object {fmt(per_object[low])} % (seed {low})."
        f"{lost_materials_text(runs)}"
    )


def generated_section(sources: Sequence[Source]) -> list[str]:
    """Evaluation objects per setting, pooled over the sweeps that ran it (each run once to
    report); development objects of every source pooled, so settings from different sweeps
    compare on common objects."""
    development, evaluation = [], []
    for source in sources:
        runs = generated_references(source.runs)
        development += [r for r in runs if object_seed(r) < EVALUATION_SEEDS_FROM]
        evaluation += [(source.label, r) for r in runs if object_seed(r) >= EVALUATION_SEEDS_FROM]
    lines = evaluation_tables(evaluation)
    if development:
        lines += development_tables(development)
    if not lines:
        return []
    return ["", "## Generated objects", "", *INTRO, "", *lines]
