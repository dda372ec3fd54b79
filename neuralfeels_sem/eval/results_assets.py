"""The shipped-checkpoints section of the results page: the held-out figures that the
training tasks wrote beside the shipped networks (`assets/*/report.json`).

Tactile depth (task=train_tactile_depth): contact IoU and depth error on the held-out
presses, overall and per finger. Material classifier (task=train_classifier /
eval_classifier): accuracy on the test split overall, per sensor, per class and per kind
of press, and on the touches the gates keep. A report that is absent or lacks a figure
leaves its rows out, never filled in.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from neuralfeels_sem.eval.results_runs import display_path, get
from neuralfeels_sem.eval.results_tables import fmt, table
from neuralfeels_sem.utils.paths import ASSETS_DIR

TACTILE_DEPTH_REPORT = ASSETS_DIR / "tactile_depth" / "report.json"
CLASSIFIER_REPORT = ASSETS_DIR / "classifier" / "report.json"


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
        f"{report.get('held_out_samples', 'n/a')} held-out presses over "
        f"{len(report.get('held_out_backgrounds') or [])} backgrounds not trained on; "
        f"training took {number(report, 'train_wall_s', digits=0)} s.",
        "",
    ]
    return head + table(["held-out", "contact IoU", "depth MAE mm"], rows)


def accuracy_rows(report: dict, group: str, label: str) -> list[list[str]]:
    rows = []
    for name, value in (get(report, group) or {}).items():
        key = f"{group}.{name}.accuracy" if isinstance(value, dict) else f"{group}.{name}"
        count = value.get("count") if isinstance(value, dict) else None
        cell = number(report, key, 100.0)
        rows.append([f"{label} `{name}`", cell + (f" ({count})" if count else "")])
    return rows


def classifier_lines(report: dict, path: Path) -> list[str]:
    rows = [
        [
            "**test split**",
            number(report, "test_accuracy", 100.0) + f" ({report.get('test_count', 'n/a')})",
        ],
        ["validation split", number(report, "val_accuracy", 100.0)],
        *accuracy_rows(report, "per_sensor", "sensor"),
        *accuracy_rows(report, "per_class", "class"),
        *accuracy_rows(report, "per_press_kind", "press"),
        [
            "touches kept by the gates (share of the test split)",
            number(report, "gated_test.kept_share", 100.0),
        ],
        ["accuracy on the kept touches", number(report, "gated_test.accuracy_kept", 100.0)],
    ]
    head = [f"### Material classifier (`{display_path(path)}`)", ""]
    return head + table(["test figure", "accuracy % (images)"], rows)


def assets_section(
    depth_report: Path = TACTILE_DEPTH_REPORT, classifier_report: Path = CLASSIFIER_REPORT
) -> Sequence[str]:
    parts: list[str] = []
    depth = read_report(depth_report)
    if depth is not None:
        parts += tactile_depth_lines(depth, depth_report) + [""]
    classifier = read_report(classifier_report)
    if classifier is not None:
        parts += classifier_lines(classifier, classifier_report) + [""]
    if not parts:
        return []
    intro = [
        "The held-out figures the training tasks wrote beside the shipped networks",
        "([perception](perception.md#figures-of-the-shipped-checkpoint),",
        "[classifier](classifier.md#the-shipped-checkpoint)); simulated data, not a real rig.",
    ]
    return ["", "## Shipped checkpoints", "", *intro, "", *parts[:-1]]
