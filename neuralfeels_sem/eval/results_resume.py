"""The resume section of the results page: runs resumed from a checkpoint beside the same
runs left uninterrupted.

A run is resumed when its `metrics.json` lists more than one segment (one per process,
see docs/evaluation.md). Its partner is the run of the same source, object, seed and
settings with one segment. Per pair: the frame the run was resumed after, mean-class
matching and plain matching of both with the difference, the majority map, and the size
of the resumed run's final checkpoint as the file on disk.
"""

from __future__ import annotations

from collections.abc import Sequence

from neuralfeels_sem.eval.results_runs import Run, Source, get
from neuralfeels_sem.eval.results_tables import fmt, setting_label, table

BYTES_PER_MB = 1e6


def segments_of(run: Run) -> list[dict]:
    segments = run.metrics.get("segments")
    return [s for s in segments if isinstance(s, dict)] if isinstance(segments, list) else []


def is_resumed(run: Run) -> bool:
    return len(segments_of(run)) > 1


def resume_pairs(source: Source) -> list[tuple[Run, Run]]:
    """(uninterrupted, resumed) pairs of the source, resumed runs without a partner left out."""
    whole = [r for r in source.runs if not is_resumed(r)]
    pairs = []
    for run in source.runs:
        if not is_resumed(run):
            continue
        for other in whole:
            same = (other.object, other.seed, other.setting) == (run.object, run.seed, run.setting)
            if same:
                pairs.append((other, run))
                break
    return pairs


def both(before: Run, after: Run, key: str) -> str:
    """'uninterrupted / resumed (difference)' of one figure."""
    a, b = get(before.metrics, key), get(after.metrics, key)
    if a is None or b is None:
        return "n/a"
    return f"{a:.2f} / {b:.2f} ({b - a:+.2f})"


def checkpoint_mb(run: Run) -> str:
    if run.checkpoint_bytes is None:
        return "n/a"
    return f"{run.checkpoint_bytes / BYTES_PER_MB:.1f}"


def resume_row(before: Run, after: Run, varying: Sequence[str]) -> list[str]:
    first = segments_of(after)[0].get("last_frame")
    floor = get(after.metrics, "baseline_majority.matching_mean_class_pct")
    floor_plain = get(after.metrics, "baseline_majority.matching_pct")
    return [
        setting_label(after, varying),
        str(after.seed),
        str(first) if first is not None else "n/a",
        both(before, after, "matching_mean_class_pct"),
        both(before, after, "matching_pct"),
        f"{fmt(floor)} / {fmt(floor_plain)}",
        checkpoint_mb(after),
    ]


HEADER = [
    "setting",
    "seed",
    "resumed after frame",
    "mean-class %: uninterrupted / resumed (difference)",
    "matching %: uninterrupted / resumed (difference)",
    "majority map %: mean-class / matching",
    "final checkpoint MB",
]


def resume_table(source: Source, pairs: Sequence[tuple[Run, Run]]) -> list[str]:
    runs = [r for pair in pairs for r in pair]
    keys = sorted({k for r in runs for k in r.setting})
    varying = [k for k in keys if len({r.setting.get(k) for r in runs}) > 1]
    constant = [k for k in keys if k not in varying]
    ordered = sorted(pairs, key=lambda p: (p[1].object, p[1].seed is None, p[1].seed or 0))
    lines = [f"### `{source.label}`", ""]
    if constant:
        fixed = ", ".join(f"`{k}={runs[0].setting[k]}`" for k in constant)
        lines += [f"Every run here: {fixed}.", ""]
    return lines + table(HEADER, [resume_row(b, a, varying) for b, a in ordered])


INTRO = [
    "Runs resumed from a checkpoint (`mapping.resume`, see",
    "[running](usage.md#interrupts-resume-and-run-directories)) beside the same run left",
    "uninterrupted in the same source: how far the resumed map ends from the uninterrupted",
    "one, and the size of the final checkpoint on disk (MB of 10^6 bytes).",
]


def resume_section(sources: Sequence[Source]) -> list[str]:
    lines: list[str] = []
    for source in sources:
        pairs = resume_pairs(source)
        if pairs:
            lines += resume_table(source, pairs) + [""]
    if not lines:
        return []
    return ["", "## Resume", "", *INTRO, "", *lines[:-1]]
