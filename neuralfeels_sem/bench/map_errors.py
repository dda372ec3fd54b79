"""Where finished runs' material maps are wrong, and why (eval/error_sources.py), per run.

Reads each run directory's config and final checkpoint (nothing is re-run), queries the
field at the run's matching samples and charges every wrong sample to its ground-truth
region's case: never pressed, pressed without a label, labelled only wrongly, or labelled
rightly (border and extrapolation errors). Also audits the readings
(eval/reading_audit.py): per material the frames that read it rightly, how right the
readings the label vote left out were, and how right the presses the classifier abstained
on would have been, and counts the trained points labelled wrongly by the kind of press
they came from (across a border, split between materials, misread). Prints one line per
run and the totals, and writes the full records as JSON.

    python -m neuralfeels_sem.bench.map_errors /work/runs/sweep/* --out errors.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch
from hydra import initialize_config_dir
from hydra.utils import instantiate

from neuralfeels_sem.configs import register_configs
from neuralfeels_sem.eval.error_sources import CASES, TouchSet, error_sources
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.eval.reading_audit import Abstentions, pool_audits, reading_audit
from neuralfeels_sem.eval.uncertainty import probability_predictor
from neuralfeels_sem.mapping.checkpoint import load_checkpoint
from neuralfeels_sem.tasks.build import BOUND_MARGIN, build_mapper, model_config
from neuralfeels_sem.tasks.eval import load_run_config
from neuralfeels_sem.utils.paths import REPO_DIR


def touch_set(mapper) -> TouchSet:
    """The mapper's touches: points, labels, and whether the material loss used each."""
    buffer = mapper.memory.touches
    state = buffer.state_dict()
    point_labels = [t.cpu().numpy().astype(np.int64) for t in state["labels"]]
    labels = np.array(state["touch_labels"], dtype=np.int64)
    used = (labels >= 0) & ~buffer.outvoted().cpu().numpy()
    points = [p.cpu().numpy().astype(np.float64) for p in state["points"]]
    used_labels = [t.cpu().numpy().astype(np.int64) for t in buffer.point_labels_used()]
    return TouchSet(points, labels, used, point_labels, used_labels)


def at_edge_of(mapper) -> np.ndarray:
    """(touches,) bool: whether each touch's imprint lay along the sensor's border."""
    return np.array(mapper.memory.touches.state_dict()["at_edge"], dtype=bool)


def abstentions(mapper) -> Abstentions:
    """The presses the classifier abstained on (no label, its probabilities kept)."""
    state = mapper.memory.touches.state_dict()
    chosen = [
        t
        for t, (labels, probs) in enumerate(zip(state["labels"], state["probs"]))
        if len(probs) and not bool((labels >= 0).any())
    ]
    classes = len(state["probs"][chosen[0]]) if chosen else 0
    return Abstentions(
        [state["points"][t].cpu().numpy().astype(np.float64) for t in chosen],
        np.array([state["probs"][t].cpu().numpy() for t in chosen]).reshape(len(chosen), classes),
        np.array([state["at_edge"][t] for t in chosen], dtype=bool),
    )


def load_run(run_dir: Path) -> tuple:
    """A finished run's config, object, mapper (its final checkpoint loaded, on the CPU) and
    matching samples. Needs the project's configs composable (inside initialize_config_dir)."""
    cfg = load_run_config(run_dir)
    obj = instantiate(cfg.object)
    mapper = build_mapper(cfg, BOUND_MARGIN * obj.bounds_radius, torch.device("cpu"))
    load_checkpoint(run_dir / "checkpoint.pt", mapper, model_config(cfg))
    matching = MatchingEvaluator(obj, int(cfg.eval.num_surface_samples), int(cfg.eval.seed))
    return cfg, obj, mapper, matching


def run_errors(run_dir: Path) -> dict:
    """The error sources of one finished mapping run (object pose: the run's ground truth)."""
    _, obj, mapper, matching = load_run(run_dir)
    probs = probability_predictor(mapper.field)(matching.points)
    touches = touch_set(mapper)
    report = error_sources(obj, matching.points, matching.faces, probs.argmax(axis=1), touches)
    metrics_file = run_dir / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
    audit = reading_audit(
        obj, touches, abstentions(mapper), list(obj.class_names), metrics.get("matching_per_class")
    )
    return {
        "run": str(run_dir),
        "object": obj.name,
        "generation": getattr(obj, "generation", None),
        "matching_mean_class_pct": metrics.get("matching_mean_class_pct"),
        "nearest_press_mean_class_pct": nearest_press_map(matching, touches),
        # Ceilings from the ground truth (diagnostic oracles): every contact point read
        # right, and every press read as the majority material under it.
        "nearest_contact_truth_mean_class_pct": nearest_contact_truth(obj, matching, touches),
        "nearest_press_truth_mean_class_pct": nearest_press_truth(obj, matching, touches),
        # How right the readings the loss trained on are, and what the same points would
        # give read perfectly (the gap to the ceiling above: presses left unread).
        **used_point_truth(obj, matching, touches),
        "wrong_trained_points": wrong_trained_points(obj, touches, at_edge_of(mapper)),
        **report,
        "readings": audit,
    }


# Which presses the wrongly labelled trained points come from (wrong_trained_points).
WRONG_KINDS = ("split", "across_border", "across_border_at_edge", "misread", "other")


def wrong_trained_points(obj, touches: TouchSet, at_edge: np.ndarray) -> dict[str, int]:
    """Trained contact points whose label is not their true material, by their press:
    `split` (its trained points carry two materials or more), `across_border` (one material
    over an imprint whose truth is less than 95 % one material; `across_border_at_edge`:
    those of edge imprints, labelled as classifier.edge_extent says), `misread` (one
    material, the wrong one, over one true material), `other` (a few points past a border
    the label is right for). Points in ignored regions are not counted."""
    counts = dict.fromkeys(WRONG_KINDS, 0)
    for t, points in enumerate(touches.points):
        labels = touches.used_labels_of(t)
        truth = obj.labels_at(points)
        judged = (labels >= 0) & (truth >= 0)
        wrong = int(np.sum(judged & (labels != truth)))
        if wrong == 0:
            continue
        shares = np.bincount(truth[judged]) / judged.sum()
        if len(np.unique(labels[judged])) > 1:
            counts["split"] += wrong
        elif shares.max() < 0.95:
            counts["across_border_at_edge" if at_edge[t] else "across_border"] += wrong
        elif shares.argmax() != labels[judged][0]:
            counts["misread"] += wrong
        else:
            counts["other"] += wrong
    return counts


def nearest_press_map(matching: MatchingEvaluator, touches: TouchSet) -> float | None:
    """Mean-class matching of the map that gives each sample the label of the nearest
    contact point of a press the material loss used (a Voronoi map of the presses)."""
    used = [
        (p[lab >= 0], lab[lab >= 0])
        for t, p in enumerate(touches.points)
        if (lab := touches.used_labels_of(t)).max() >= 0
    ]
    if not used:
        return None
    points = np.concatenate([p for p, _ in used])
    labels = np.concatenate([lab for _, lab in used])
    return matching.nearest_scores(points, labels)["matching_mean_class_pct"]


def nearest_contact_truth(obj, matching: MatchingEvaluator, touches: TouchSet) -> float | None:
    """Oracle: each sample takes the true material of the nearest contact point of any
    press (labelled or not): what the presses' placement allows with perfect reading."""
    if not touches.points:
        return None
    points = np.concatenate(touches.points)
    truth = obj.labels_at(points)
    keep = truth >= 0
    return matching.nearest_scores(points[keep], truth[keep])["matching_mean_class_pct"]


def nearest_press_truth(obj, matching: MatchingEvaluator, touches: TouchSet) -> float | None:
    """Oracle: every press labelled with the majority true material under it, all used."""
    labels = []
    for p in touches.points:
        truth = obj.labels_at(p)
        truth = truth[truth >= 0]
        labels.append(int(np.bincount(truth).argmax()) if len(truth) else -1)
    labels = np.array(labels)
    oracle = TouchSet(touches.points, labels, labels >= 0)
    return nearest_press_map(matching, oracle)


USED_POINT_FIGURES = (
    "used_point_accuracy_pct",
    "nearest_used_point_truth_mean_class_pct",
    "nearest_right_point_mean_class_pct",
    "used_points_ignored_pct",
)


def used_point_truth(obj, matching: MatchingEvaluator, touches: TouchSet) -> dict:
    """How right the contact points the material loss trained on are, and what they map.

    `used_point_accuracy_pct`: share of them in the scored regions whose label is their true
    material; `nearest_used_point_truth_mean_class_pct`: the oracle map that gives each
    sample the true material of the nearest such point; `nearest_right_point_mean_class_pct`:
    the map of the nearest rightly labelled one (the wrong and the ignored ones left out:
    beside `nearest_press_mean_class_pct`, what the wrong readings cost a map of these
    presses); `used_points_ignored_pct`: share of all of them on ignored faces (seams, the
    face the object rests on: unscored, but they train the map beside scored faces). All
    None without such points in the scored regions."""
    out = dict.fromkeys(USED_POINT_FIGURES)
    if not touches.points:
        return out
    used = [touches.used_labels_of(t) for t in range(len(touches.points))]
    points = np.concatenate([p[lab >= 0] for p, lab in zip(touches.points, used)])
    labels = np.concatenate([lab[lab >= 0] for lab in used])
    truth = obj.labels_at(points)
    scored = truth >= 0
    if not scored.any():
        return out
    right = scored & (labels == truth)
    nearest_truth = matching.nearest_scores(points[scored], truth[scored])
    out["used_point_accuracy_pct"] = float(100.0 * np.mean(labels[scored] == truth[scored]))
    out["nearest_used_point_truth_mean_class_pct"] = nearest_truth["matching_mean_class_pct"]
    if right.any():
        nearest_right = matching.nearest_scores(points[right], labels[right])
        out["nearest_right_point_mean_class_pct"] = nearest_right["matching_mean_class_pct"]
    out["used_points_ignored_pct"] = float(100.0 * np.mean(~scored))
    return out


def summary_line(row: dict) -> str:
    lost = row["by_case"]
    parts = " ".join(f"{c}={lost[c]['mean_class_points_lost']:5.1f}" for c in CASES)
    family = (row.get("generation") or {}).get("family", "")
    nan = float("nan")
    voronoi = row["nearest_press_mean_class_pct"] or nan
    ceilings = (
        f"{row['nearest_press_truth_mean_class_pct'] or nan:5.1f}/"
        f"{row['nearest_contact_truth_mean_class_pct'] or nan:5.1f}"
    )
    used = (
        f"{row['used_point_accuracy_pct'] or nan:5.1f}/"
        f"{row['nearest_used_point_truth_mean_class_pct'] or nan:5.1f}"
    )
    return (
        f"{row['object']:>14} {family:>11} mean-class {row['matching_mean_class_pct'] or nan:5.1f}"
        f" (nearest press {voronoi:5.1f}, true presses/points {ceilings},"
        f" trained points right %/read true {used})  lost: {parts}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories (task=map)")
    parser.add_argument("--out", type=Path, default=None, help="write every record as JSON")
    args = parser.parse_args(argv)
    rows = []
    register_configs()
    with initialize_config_dir(config_dir=str(REPO_DIR / "conf"), version_base="1.3"):
        for run_dir in args.runs:
            if not (run_dir / "checkpoint.pt").is_file():
                continue
            rows.append(run_errors(run_dir))
            print(summary_line(rows[-1]), flush=True)
    totals = {
        c: float(np.mean([r["by_case"][c]["mean_class_points_lost"] for r in rows])) for c in CASES
    }
    print(
        "mean points of mean-class matching lost per run:",
        {c: round(v, 1) for c, v in totals.items()},
    )
    wrong = {k: sum(r["wrong_trained_points"][k] for r in rows) for k in WRONG_KINDS}
    print("wrongly labelled trained points, by their press:", wrong)
    print("mean over runs:", mean_figures(rows))
    pooled = pool_audits([r["readings"] for r in rows])
    print(pooled_lines(pooled))
    if args.out is not None:
        record = {
            "mean_points_lost": totals,
            "wrong_trained_points": wrong,
            "readings": pooled,
            "runs": rows,
        }
        args.out.write_text(json.dumps(record, indent=1))


def mean_figures(rows: list[dict]) -> dict[str, float | None]:
    """The runs' map and its nearest-point maps, averaged over the runs that have each."""
    keys = ("matching_mean_class_pct", "nearest_press_mean_class_pct", *USED_POINT_FIGURES)
    means = {}
    for key in keys:
        values = [r[key] for r in rows if r.get(key) is not None]
        means[key] = round(float(np.mean(values)), 2) if values else None
    return means


def pooled_lines(pooled: dict) -> str:
    """The pooled reading audit as a few lines of text."""

    def pct(value: float | None) -> str:
        return "  -" if value is None else f"{value:3.0f}"

    bins = [
        f"{b['from']}{'+' if b['to'] is None else '-' + str(b['to'])}: {b['materials']}"
        f" (recall {pct(b['mean_recall_pct'])} %)"
        for b in pooled["materials_by_frames_right"]
    ]
    lines = ["materials by frames read rightly: " + ", ".join(bins)]
    out = pooled["outvoted"]
    lines.append(f"readings the vote left out: {out['readings']}, right {pct(out['right_pct'])} %")
    for reason, rows in pooled["abstained_by_confidence"].items():
        cells = [f">={r['from']}: {pct(r['right_pct'])} % of {r['frames']}" for r in rows]
        lines.append(f"abstained ({reason}), top class right by confidence: " + ", ".join(cells))
    rare = pooled["abstained_rare_material"]
    lines.append(
        f"abstained readings naming a material the map nearly lacks: {rare['frames']},"
        f" right {pct(rare['right_pct'])} %"
    )
    return "\n".join(lines)


if __name__ == "__main__":
    main()
