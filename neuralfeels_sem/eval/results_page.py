"""The results page (docs/results.md) from run outputs; the command is tasks/results_page.py.

    python -m neuralfeels_sem.tasks.results_page --out docs/results.md [--readme README.md]
        [--bench bench.json] DIR [DIR ...]

Each DIR is a run directory (holds `metrics.json`) or a sweep directory (job
sub-directories with `metrics.json` and `.hydra/overrides.yaml`, as `-m` writes them).
The page has these parts:
- multi-material objects (default config): mean-class matching per seed and mean ± std,
  beside the majority-material map and the margin over it; matching and shape-aware
  matching, F-score, classifier accuracy on judged touches and coverage;
- single-material objects (the majority map already scores 100 %): classifier accuracy on
  judged touches, coverage, accuracy over all touches, F-score;
- uncertainty of the material map: entropy against the map's errors (results_uncertainty.py);
- pose tracking: runs with `mapping.pose` other than `gt`, per run and per object, beside
  the `pose=gt` run of the same object and seed (results_pose.py);
- active touch: `sensor.policy` runs, scripted against active per object and seed
  (results_policy.py);
- resume: runs resumed from a checkpoint beside the same runs uninterrupted
  (results_resume.py);
- every other setting (ablations, runs with overrides), one table per source;
- shipped checkpoints: the held-out figures in the reports beside the shipped networks
  (results_assets.py);
- speed, from `make bench` reports (`--bench bench.json`, repeated for each machine, a
  GPU's too), each figure with its load;
- per source: the simulator oracles the runs used, the machine and load where recorded,
  and when the runs finished.
A run belongs to the first two parts when it ran today's default config: its only overrides
are the object, the seed and bookkeeping (experiment preset, launcher, perception preset,
viz.plots, hydra.*) or set today's default value, and no default it ran with has changed
since (results_drift.py); anything else makes it a setting.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.eval.results_assets import assets_section
from neuralfeels_sem.eval.results_bench import speed_section
from neuralfeels_sem.eval.results_code import BEHAVIOUR_CHANGES
from neuralfeels_sem.eval.results_drift import show
from neuralfeels_sem.eval.results_generated import (
    evaluation_runs_at_defaults,
    evaluation_summary,
    generated_references,
    generated_section,
    is_generated,
)
from neuralfeels_sem.eval.results_policy import is_policy_run, policy_section
from neuralfeels_sem.eval.results_pose import pose_runs, pose_section
from neuralfeels_sem.eval.results_resume import resume_pairs, resume_section
from neuralfeels_sem.eval.results_runs import (
    Run,
    Source,
    describe_oracles,
    display_path,
    oracles_of,
)
from neuralfeels_sem.eval.results_scanned import is_scanned, scanned_references, scanned_section
from neuralfeels_sem.eval.results_tables import (
    multi_material_table,
    perception_table,
    settings_table,
    single_material_table,
    values_of,
)
from neuralfeels_sem.eval.results_uncertainty import uncertainty_section

COMMAND = "python -m neuralfeels_sem.tasks.results_page"  # the wiring that calls render()


# ---------------------------------------------------------------------------- sources
def machine_text(runs: Sequence[Run]) -> str:
    """The machines the runs used (each once) and the range of their 1-minute load averages."""
    machines, loads = [], []
    for run in runs:
        machine, load = run.metrics.get("machine"), run.metrics.get("load_avg")
        if isinstance(machine, dict):
            machine = ", ".join(f"{k} {v}" for k, v in machine.items())
        if machine and str(machine) not in machines:
            machines.append(str(machine))
        if isinstance(load, list | tuple) and load:
            load = load[0]
        if isinstance(load, int | float):
            loads.append(float(load))
    parts = [" | ".join(machines)] if machines else []
    if loads:
        low, high = min(loads), max(loads)
        span = f"{low:.1f}" if low == high else f"{low:.1f}-{high:.1f}"
        parts.append(f"1-minute load average at the end of the runs {span}")
    return "; ".join(parts) if parts else "not recorded"


def code_text(runs: Sequence[Run]) -> str:
    """The commits the runs ran (metrics.json `code`), local changes counted."""
    commits: dict[str, int] = {}
    dirty = unknown = 0
    for run in runs:
        code = run.metrics.get("code") or {}
        if not code.get("commit"):
            unknown += 1
            continue
        commits[code["commit"][:10]] = commits.get(code["commit"][:10], 0) + 1
        dirty += bool(code.get("dirty"))
    if not commits:
        return "code version not recorded"
    text = "commit " + ", ".join(
        f"{c}" if len(commits) == 1 else f"{c} ({plural(n, 'run')})" for c, n in commits.items()
    )
    if dirty:
        text += f"; {plural(dirty, 'run')} with local changes"
    if unknown:
        text += f"; {plural(unknown, 'run')} without a recorded version"
    return text


def written_text(runs: Sequence[Run]) -> str:
    """When the runs finished: the UTC range of their metrics.json modification times."""
    stamps = [run.finished_at for run in runs if run.finished_at is not None]
    if not stamps:
        return "finish time not known"
    low, high = (
        datetime.fromtimestamp(t, tz=UTC).strftime("%Y-%m-%d %H:%M")
        for t in (min(stamps), max(stamps))
    )
    return f"finished {low if low == high else f'{low} to {high}'} UTC"


def plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def drift_lines(runs: Sequence[Run]) -> list[str]:
    """A sub-bullet naming the defaults changed since the runs (they count as settings)."""
    changed: dict[str, set[str]] = {}
    for run in runs:
        for key, (then, now) in run.drift.items():
            changed.setdefault(key, set()).add(f"{show(then)} (today {show(now)})")
    if not changed:
        return []
    items = "; ".join(
        f"`{key}` {', '.join(sorted(v))}{what_changed(key)}" for key, v in sorted(changed.items())
    )
    return [f"  - defaults changed since these runs, so shown as their settings: {items}"]


def what_changed(key: str) -> str:
    """` (what changed)` for a behaviour change without a config key (results_code.py)."""
    change = BEHAVIOUR_CHANGES.get(key)
    return f" ({change.what})" if change else ""


def source_lines(source: Source) -> list[str]:
    """A bullet per source: what it holds, then its oracles and machine as sub-bullets."""
    if source.kind == "run":
        what = "run directory"
    else:
        what = f"sweep: {plural(len(source.runs), 'run')} with metrics.json"
        if source.failed:
            what += f"; {len(source.failed)} failed: " + ", ".join(source.failed)
        if source.missing:
            what += f"; {len(source.missing)} without results: " + ", ".join(source.missing)
    found: dict[tuple[str, ...] | None, list[str]] = {}
    for run in source.runs:
        names, origin = oracles_of(run)
        found.setdefault(names, []).append(origin)
    lines = [f"- `{source.label}` ({what})"]
    for names, origins in found.items():
        who = "" if len(found) == 1 else f"{plural(len(origins), 'run')}, "
        if names is None:
            lines.append(
                f"  - oracles ({who}not recorded): no `oracles` in metrics.json "
                "and no .hydra/config.yaml"
            )
        else:
            where = ", ".join(sorted(set(origins)))
            lines.append(f"  - oracles ({who}from {where}): {describe_oracles(names)}")
    lines += drift_lines(source.runs)
    wall = values_of(source.runs, "wall_s")
    machine = f"  - machine/load: {machine_text(source.runs)}"
    if wall:
        low, high = f"{min(wall):.0f}", f"{max(wall):.0f}"
        machine += f"; wall time per run {low if low == high else f'{low}-{high}'} s"
    return lines + [machine, f"  - {code_text(source.runs)}; {written_text(source.runs)}"]


# ---------------------------------------------------------------------------- page
INTRO = [
    "The headline figure is mean-class matching (the mean over the materials present of",
    "each material's recall), always beside the majority map (a constant map painting the",
    "whole object in its majority material) and the margin between them. Plain matching is",
    "shown with the majority map's figure in brackets. Classifier figures are means over",
    "runs; every metric is defined in [evaluation](evaluation.md).",
]


def material_sections(runs: Sequence[Run]) -> list[str]:
    """The default-config runs: multi-material objects, then single-material ones."""
    default = [r for r in runs if not r.setting]
    multi = [r for r in default if not r.single_material]
    single = [r for r in default if r.single_material]
    lines = ["## Multi-material objects", ""]
    lines += multi_material_table(multi) if multi else ["No default-config multi-material runs."]
    lines += [
        "",
        "## Single-material objects",
        "",
        "The majority map scores 100 % here, so these objects are reported by the classifier:",
        "accuracy on judged touches, coverage (share of touches that got a label) and accuracy",
        "over all touches (an abstention counts as not correct). Beside them, the share of the",
        "scored surface the map paints in the object's one material (plain matching; a constant",
        "map scores 100 %): below 100 where the map paints part of it another material, e.g.",
        "from presses outside the scored regions (sockets, bases), which the classifier figures",
        "leave out.",
        "",
    ]
    return lines + (single_material_table(single) if single else ["No single-material runs."])


def perception_section(runs: Sequence[Run]) -> list[str]:
    # A realtime run perceives only the few frames it maps: its figures would weigh as
    # much as a whole run's in the mean, so the table keeps to offline runs.
    table = perception_table([r for r in runs if r.metrics.get("pace") != "realtime"])
    if not table:
        return []
    return [
        "",
        "## Perception against the simulator's ground truth",
        "",
        'Mean ± std over runs of the per-run figures of `metrics.json["perception"]`:',
        "the segmented camera mask's IoU with the true object mask, camera frames whose",
        "object could not be found (skipped, never fused), and the touches' contact IoU and",
        "depth error on true contact pixels (see [perception](perception.md)); runs at",
        "`sensor.pace=offline`, every setting of the object and oracles pooled.",
        "",
        *table,
    ]


def own_section_runs(source: Source) -> list[Run]:
    """Tracked runs (with their `pose=gt` partners), active-touch runs, resume pairs and
    runs on generated objects or scanned meshes with drawn layouts: they have sections of
    their own, not the object or settings tables. A policy sweep's scripted runs at today's
    defaults are default runs: they are in the tables too (and in the active-touch section)."""
    tracked, partners = pose_runs(source)
    resumed = [r for pair in resume_pairs(source) for r in pair]
    policy = [r for r in source.runs if is_policy_run(r) and r.setting]
    own = [r for r in source.runs if is_generated(r) or is_scanned(r)]
    return tracked + partners + resumed + policy + own


def table_runs(sources: Sequence[Source]) -> list[Run]:
    """The runs of the object, perception and settings tables: all but those of a section
    of their own, and default-config repeats: a run of an object, seed and oracles that an
    earlier run on the page already gives at today's defaults (e.g. the baseline a live-view
    source reruns beside its view) would count that seed twice."""
    own = {id(r) for s in sources for r in own_section_runs(s)}
    seen, out = set(), []
    for run in (r for s in sources for r in s.runs if id(r) not in own):
        key = (run.object, run.seed, oracles_of(run)[0])
        if not run.setting:
            if key in seen:
                continue
            seen.add(key)
        out.append(run)
    return out


def settings_sections(sources: Sequence[Source]) -> list[str]:
    """One table per source for its runs with other settings (ablations, overrides)."""
    lines = ["", "## Other settings", ""]
    other = False
    for source in sources:
        own = {id(r) for r in own_section_runs(source)}
        members = [r for r in source.runs if r.setting and id(r) not in own]
        if members:
            lines += settings_table(source, members) + [""]
            other = True
    return lines if other else lines + ["No runs with other settings.", ""]


def render(
    sources: Sequence[Source],
    command: str,
    benches: Sequence[Path] = (),
    locate: Callable[[Path], Path] = lambda path: path,
) -> str:
    """The page. `locate`: where to read each bench report named by `benches` (an archived
    copy, eval/results_archive.py, where the file is gone)."""
    runs = table_runs(sources)
    # What tracked and active-touch runs are compared with: default-config runs, and runs
    # on generated objects or scanned meshes with the simulator's pose (their own
    # sections' tables).
    every = [r for s in sources for r in s.runs]
    references = runs + generated_references(every) + scanned_references(every)
    lines = [
        "# Results",
        "",
        "<!-- Generated file: do not edit by hand. -->",
        "This page is generated from run outputs by",
        "",
        "```bash",
        command,
        "```",
        "",
        *INTRO,
        "",
        *material_sections(runs),
        *perception_section(runs),
        *uncertainty_section(sources, runs),
        *generated_section(sources),
        *scanned_section(sources),
        *pose_section(sources, references),
        *policy_section(sources, references),
        *resume_section(sources),
        *settings_sections(sources),
        *assets_section(),
        *speed_section(benches, locate),
        "",
        "## Sources",
        "",
    ]
    for source in sources:
        lines += source_lines(source)
    return "\n".join(lines) + "\n"


README_BEGIN = "<!-- results-table: generated by eval/results_page.py --readme; do not edit -->"
README_END = "<!-- results-table end -->"


def provenance_text(runs: Sequence[Run]) -> str:
    """Which code, when and where runs ran, as the README states it under its figures."""
    return (
        f"*Runs: {code_text(runs)}; {written_text(runs)}; machine and load: {machine_text(runs)}.*"
    )


def update_readme(path: Path, sources: Sequence[Source]) -> None:
    """Replace the README's results table (between its two markers) by the multi-material
    table of the page, so the front page quotes the generated figures."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror})") from None
    if text.count(README_BEGIN) != 1 or text.count(README_END) != 1:
        raise DataError(f"{path}: needs one '{README_BEGIN}' line and one '{README_END}' line")
    runs = [r for r in table_runs(sources) if not r.setting and not r.single_material]
    if not runs:
        raise DataError("--readme: no default-config multi-material runs among the directories")
    head, rest = text.split(README_BEGIN)
    tail = rest.split(README_END)[1]
    stated = provenance_text(runs)
    lines = [README_BEGIN, *multi_material_table(runs), "", stated]
    unseen = evaluation_runs_at_defaults(sources)
    if unseen:
        lines += ["", evaluation_summary(unseen) + " " + provenance_text(unseen)]
    body = "\n".join([*lines, README_END])
    try:
        path.write_text(head + body + tail)
    except OSError as exc:
        raise DataError(f"{path}: cannot write ({exc.strerror})") from None


def build_command(
    out: Path | None,
    dirs: Sequence[str],
    benches: Sequence[Path] = (),
    readme: Path | None = None,
    archive: Path | None = None,
) -> str:
    parts = [COMMAND] + ([f"--out {display_path(out)}"] if out is not None else [])
    parts += [f"--readme {display_path(readme)}"] if readme is not None else []
    parts += [f"--archive {display_path(archive)}"] if archive is not None else []
    parts += [f"--bench {display_path(bench)}" for bench in benches]
    return " ".join(parts + [display_path(Path(d)) for d in dirs])
