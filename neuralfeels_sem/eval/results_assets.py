"""The shipped-checkpoints section of the results page: the held-out figures that the
training tasks wrote beside the shipped networks (`assets/*/report.json`).

Tactile depth (task=train_tactile_depth): its training data and time, and contact IoU
and depth error on the held-out presses, overall and per finger. Material classifier
(task=train_classifier / eval_classifier): its training data (with the kinds of press its
`manifest.json` records), split and last training round; accuracy on the test split
overall, per sensor, per class and per kind of press, and on the touches the gates keep,
with what they left out and why; the confusion matrix; and the same checkpoint on fresh
collections (`held_out_*.json`): per kind of press and per bend radius of the surface
pressed. A figure a report lacks is shown
as n/a, never filled in; an absent report leaves its part out.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from neuralfeels_sem.eval.results_runs import display_path, get
from neuralfeels_sem.eval.results_tables import fmt, table
from neuralfeels_sem.perception.classifier.evaluate import curvature_bin_labels
from neuralfeels_sem.utils.paths import ASSETS_DIR

TACTILE_DEPTH_REPORT = ASSETS_DIR / "tactile_depth" / "report.json"
CLASSIFIER_REPORT = ASSETS_DIR / "classifier" / "report.json"
# task=eval_classifier reports of the shipped checkpoint on collections made apart from its
# training data (assets/classifier/README.md says how each was made).
CLASSIFIER_HELD_OUT = tuple(sorted((ASSETS_DIR / "classifier").glob("held_out_*.json")))


def read_report(path: Path) -> dict | None:
    try:
        report = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return report if isinstance(report, dict) else None


def number(report: dict, dotted: str, scale: float = 1.0, digits: int = 1) -> str:
    value = get(report, dotted)
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    return fmt(scale * float(value), digits) if ok else "n/a"


def text(report: dict, dotted: str) -> str:
    """A setting or count as the report wrote it (n/a when absent)."""
    value = get(report, dotted)
    return "n/a" if value is None or isinstance(value, dict | list) else str(value)


def count(report: dict, dotted: str) -> str:
    value = get(report, dotted)
    return str(len(value)) if isinstance(value, list) else "n/a"


def tactile_depth_lines(report: dict, path: Path) -> list[str]:
    rows = [["**overall**", number(report, "held_out.overall.contact_iou", digits=3)]]
    rows[0].append(number(report, "held_out.overall.depth_mae_mm", digits=3))
    for finger in get(report, "held_out.per_finger") or {}:
        key = f"held_out.per_finger.{finger}"
        rows.append(
            [finger, number(report, f"{key}.contact_iou", digits=3)]
            + [number(report, f"{key}.depth_mae_mm", digits=3)]
        )
    head = [
        f"### Tactile depth network (`{display_path(path)}`)",
        "",
        f"Trained on {text(report, 'train_samples')} presses over "
        f"{count(report, 'train_backgrounds')} backgrounds, {text(report, 'settings.epochs')} "
        f"epochs at batch {text(report, 'settings.batch_size')}; training took "
        f"{number(report, 'train_wall_s', digits=0)} s. Held out: "
        f"{text(report, 'held_out_samples')} presses over "
        f"{count(report, 'held_out_backgrounds')} backgrounds not trained on.",
        "",
    ]
    return head + table(["held-out", "contact IoU", "depth MAE mm"], rows)


def accuracy_rows(
    report: dict, group: str, label: str, order: Sequence[str] = ()
) -> list[list[str]]:
    """One row per entry of `group`, those named in `order` first and in that order."""
    rows = []
    entries = get(report, group) or {}
    names = [n for n in order if n in entries] + [n for n in entries if n not in order]
    for name in names:
        value = entries[name]
        key = f"{group}.{name}.accuracy" if isinstance(value, dict) else f"{group}.{name}"
        count = value.get("count") if isinstance(value, dict) else None
        cell = number(report, key, 100.0)
        rows.append([f"{label} `{name}`", cell + (f" ({count})" if count else "")])
    return rows


def press_rows(report: dict) -> list[list[str]]:
    """Accuracy per kind of press and per bend radius of the surface pressed."""
    return accuracy_rows(report, "per_press_kind", "press") + accuracy_rows(
        report, "per_curvature", "bend radius", curvature_bin_labels()
    )


def classifier_lines(report: dict, path: Path) -> list[str]:
    rows = [
        [
            "**test split**",
            number(report, "test_accuracy", 100.0) + f" ({report.get('test_count', 'n/a')})",
        ],
        ["validation split", number(report, "val_accuracy", 100.0)],
        *accuracy_rows(report, "per_sensor", "sensor"),
        *accuracy_rows(report, "per_class", "class"),
        *press_rows(report),
        [
            "touches kept by the gates (share of the test split)",
            number(report, "gated_test.kept_share", 100.0),
        ],
        ["accuracy on the kept touches", number(report, "gated_test.accuracy_kept", 100.0)],
    ]
    head = [f"### Material classifier (`{display_path(path)}`)", ""]
    head += classifier_training_lines(report, read_report(path.parent / "manifest.json"))
    rows_table = table(["test figure", "accuracy % (images)"], rows)
    return head + rows_table + gate_lines(report) + confusion_lines(report)


def classifier_training_lines(report: dict, manifest: dict | None) -> list[str]:
    """What the checkpoint was trained on and how its last round ran."""
    kinds = get(manifest or {}, "dataset.press_counts") or {}
    presses = ", ".join(f"{kind} {n}" for kind, n in kinds.items())
    mix = get(report, "training.mix")
    mixed = (
        f"; each epoch mixed with {text(report, 'training.mix.sim_per_epoch')} draws from "
        f"{text(report, 'training.mix.sim_images')} simulated presses of another collection"
        if isinstance(mix, dict)
        else ""
    )
    return [
        f"Data set: {text(report, 'data.images')} simulated images"
        + (f" (presses: {presses})" if presses else "")
        + f", split {text(report, 'counts.train')} / {text(report, 'counts.val')} / "
        f"{text(report, 'counts.test')} (train / validation / test){mixed}. Last training "
        f"round: {text(report, 'training.epochs_run')} epochs, lr {text(report, 'training.lr')} "
        f"({text(report, 'training.lr_schedule')}), batch {text(report, 'training.batch_size')}; "
        f"kept epoch {text(report, 'training.best_epoch')}, the best on validation.",
        "",
    ]


def gate_lines(report: dict) -> list[str]:
    """What the mapper's gates did on the test split (absent from older reports)."""
    if not isinstance(get(report, "gated_test"), dict):
        return []
    return [
        "",
        f"The gates (confidence >= {text(report, 'gated_test.min_confidence')}, edge share "
        f"<= {text(report, 'gated_test.max_edge_share')}) kept "
        f"{text(report, 'gated_test.kept_count')} of {text(report, 'test_count')} test images; "
        f"they left out {text(report, 'gated_test.left_out_low_confidence')} for low "
        f"confidence and {text(report, 'gated_test.left_out_edge')} for a contact near the "
        "gel's border.",
    ]


def confusion_lines(report: dict) -> list[str]:
    """The test split's confusion matrix, rows the true class, columns the predicted one."""
    names, matrix = report.get("class_names"), report.get("confusion")
    if not isinstance(names, list) or not isinstance(matrix, list) or len(names) != len(matrix):
        return []
    rows = [[f"`{name}`", *(str(n) for n in row)] for name, row in zip(names, matrix)]
    return [
        "",
        "Confusion on the test split (rows: true class; columns: predicted):",
        "",
        *table(["true class", *(f"`{n}`" for n in names)], rows),
    ]


def held_out_lines(report: dict, path: Path) -> list[str]:
    """The shipped classifier on a fresh collection: overall, per kind of press and per
    bend radius of the surface pressed, and at the mapper's gates."""
    rows = [
        [
            "**all images**",
            number(report, "test_accuracy", 100.0) + f" ({text(report, 'test_count')})",
        ],
        *press_rows(report),
        ["touches kept by the gates (share)", number(report, "gated.kept_share", 100.0)],
        ["accuracy on the kept touches", number(report, "gated.accuracy_kept", 100.0)],
    ]
    root = get(report, "data.root")
    head = [
        f"### Material classifier on a held-out collection (`{display_path(path)}`)",
        "",
        "Simulated images no training round used"
        + (f" (`{display_path(Path(str(root)))}`)" if root else "")
        + ", judged by the shipped checkpoint: presses of `task=collect_tactile`, or the "
        "rig's own touches (`bench.rig_touches`). The bend radius is the surface's at the "
        "press: one over its largest principal curvature over the gel's footprint.",
        "",
    ]
    return head + table(["held-out figure", "accuracy % (images)"], rows)


def assets_section(
    depth_report: Path = TACTILE_DEPTH_REPORT,
    classifier_report: Path = CLASSIFIER_REPORT,
    held_out: Sequence[Path] = CLASSIFIER_HELD_OUT,
) -> Sequence[str]:
    parts: list[str] = []
    depth = read_report(depth_report)
    if depth is not None:
        parts += tactile_depth_lines(depth, depth_report) + [""]
    classifier = read_report(classifier_report)
    if classifier is not None:
        parts += classifier_lines(classifier, classifier_report) + [""]
    for path in held_out:
        report = read_report(path)
        if report is not None:
            parts += held_out_lines(report, path) + [""]
    if not parts:
        return []
    intro = [
        "The held-out figures the training tasks wrote beside the shipped networks",
        "([perception](perception.md#figures-of-the-shipped-checkpoint),",
        "[classifier](classifier.md#the-shipped-checkpoint)); simulated data, not a real rig.",
    ]
    return ["", "## Shipped checkpoints", "", *intro, "", *parts[:-1]]
