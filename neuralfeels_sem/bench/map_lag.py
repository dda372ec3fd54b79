"""How soon a finished run's material map was right, against how soon its touches allowed.

Reads each run directory's config, final checkpoint and matching curve (nothing is
re-run). Every `--every` seconds of sensor time (the latest curve point by then) and at
the run's end it sets the field's own mean-class matching (the run's curve) beside two
maps built from the touches made by then, each a nearest-point map on the run's matching
samples (a sample takes the label of the nearest contact point):
- `readings`: the classifier's labels of those touches (abstentions left out, the label
  vote not applied): what the readings so far support;
- `kept`: the labels of those touches that the label vote keeps among them, the points the
  material loss and the fill trained on by then: what the map could follow;
- `placement`: the true material of every contact point so far, read or not (an oracle
  of the simulator): what the places pressed allow with perfect reading.
The sensor time at which each first reaches `--level` tells what holds a run back: a
field that reaches it long after `kept` learns or extrapolates slower than its touches
allow; `kept` long after `readings` means the vote held readings back; a late `placement`
means the fingers had not yet pressed enough of the object (where the object turned them
and where the touch policy put them).

    python -m neuralfeels_sem.bench.map_lag multirun/sweep/* --out lag.json --plot lag.png
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from hydra import initialize_config_dir

from neuralfeels_sem.bench.map_errors import load_run, touch_set
from neuralfeels_sem.configs import register_configs
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.mapping.touch_memory import TouchBuffer
from neuralfeels_sem.utils.paths import REPO_DIR
from neuralfeels_sem.viz.lag_plot import plot_map_lag

SERIES = ("field", "kept", "readings", "placement")
# frame -> the contact points and labels the label vote keeps among the touches made by then
KeptLabels = Callable[[int], tuple[np.ndarray, np.ndarray]]


def touch_history(mapper) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """The mapper's touches in arrival order: contact points (object frame), the
    classifier's label of each point (-1: abstained or geometry only), frame index."""
    touches = touch_set(mapper)
    labels = [touches.labels_of(t) for t in range(len(touches.points))]
    frames = mapper.memory.touches.state_dict()["frames"]
    return touches.points, labels, np.asarray(frames, dtype=np.int64)


def kept_upto(buffer: TouchBuffer) -> KeptLabels:
    """The vote's choice as the mapper made it at each frame: the buffer's touches of frames
    up to it voted on alone (the vote depends only on those; with press fusion on, a touch's
    fused label counts from its own frame)."""
    state = buffer.state_dict()
    per_touch = [k for k, v in state.items() if isinstance(v, list) and k != "mapped_frames"]

    def kept(frame: int) -> tuple[np.ndarray, np.ndarray]:
        chosen = [i for i, f in enumerate(state["frames"]) if f <= frame]
        if not chosen:
            return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
        past_state = {**state, **{k: [state[k][i] for i in chosen] for k in per_touch}}
        past_state["mapped_frames"] = [f for f in state["mapped_frames"] if f <= frame]
        past_state["num_touches"] = len(chosen)
        past_state["num_labelled"] = sum(state["touch_labels"][i] >= 0 for i in chosen)
        past = TouchBuffer(torch.device("cpu"), vote=buffer.vote)
        past.load_state_dict(past_state)
        points = torch.cat([p.cpu() for p in past_state["points"]]).double().numpy()
        labels = torch.cat([t.cpu() for t in past.point_labels_used()]).numpy()
        return points, labels.astype(np.int64)

    return kept


def lag_rows(
    obj,
    matching: MatchingEvaluator,
    history: tuple[list[np.ndarray], list[np.ndarray], np.ndarray],
    curve: list[list[float]],
    every_s: float,
    kept: KeptLabels | None = None,
) -> list[dict]:
    """Rows (time, frame and the four series) at the curve's points, every `every_s` of
    sensor time: at each multiple of it, the latest curve point not after it. Without
    `kept` that series is None."""
    if every_s <= 0:
        raise ValueError(f"--every={every_s} must be > 0 seconds")
    points, labels, frames = history
    series: dict[str, np.ndarray] = {}  # per contact point: its label in each touch map
    if points:
        every = np.concatenate(points)
        point_frames = np.repeat(frames, [len(p) for p in points])
        # The true material of every contact point, once: the closest-face query is the cost.
        series = {"readings": np.concatenate(labels), "placement": obj.labels_at(every)}
    rows = []
    for frame, time_s, field_pct in sampled(curve, every_s):
        row = {"time_s": float(time_s), "frame": int(frame), "field": float(field_pct)}
        row.update(kept=None, readings=None, placement=None)
        for key, point_labels in series.items():
            keep = (point_frames <= frame) & (point_labels >= 0)
            if keep.any():
                scores = matching.nearest_scores(every[keep], point_labels[keep])
                row[key] = scores["matching_mean_class_pct"]
        if kept is not None:
            kept_points, kept_labels = kept(int(frame))
            used = kept_labels >= 0
            if used.any():
                scores = matching.nearest_scores(kept_points[used], kept_labels[used])
                row["kept"] = scores["matching_mean_class_pct"]
        rows.append(row)
    return rows


def sampled(curve: list[list[float]], every_s: float) -> list[list[float]]:
    """The curve's (frame, time, value) points at the latest one not after each multiple of
    `every_s`, and its last (the run's end); each point once."""
    times = np.array([p[1] for p in curve], dtype=np.float64)
    if len(times) == 0:
        return []
    grid = np.arange(0.0, times[-1] + 1e-6, every_s)
    picked = np.searchsorted(times, grid + 1e-6, side="right") - 1
    return [curve[i] for i in sorted({*picked[picked >= 0].tolist(), len(curve) - 1})]


def first_reached(rows: list[dict], key: str, level: float) -> float | None:
    """Sensor time (s) of the first row whose `key` is at least `level` (None: never)."""
    return next((r["time_s"] for r in rows if r[key] is not None and r[key] >= level), None)


def run_lag(run_dir: Path, every_s: float, level: float) -> dict:
    """The three series of one finished run and when each first reached `level`."""
    cfg, obj, mapper, matching = load_run(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    rows = lag_rows(
        obj,
        matching,
        touch_history(mapper),
        metrics.get("matching_mean_class_curve") or [],
        every_s,
        kept_upto(mapper.memory.touches),
    )
    return {
        "run": str(run_dir),
        "object": obj.name,
        "seed": int(cfg.seed),
        "policy": str(cfg.sensor.get("policy", "-")),
        "level": level,
        "first_reached_s": {k: first_reached(rows, k, level) for k in SERIES},
        "rows": rows,
    }


def summary_line(record: dict) -> str:
    reached = record["first_reached_s"]
    parts = [f"{k} {'-' if reached[k] is None else f'{reached[k]:.1f} s'}" for k in SERIES]
    return (
        f"{record['object']} seed {record['seed']} {record['policy']}: "
        f"first at {record['level']:g} % mean-class: " + ", ".join(parts)
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories (task=map)")
    parser.add_argument("--every", type=float, default=0.5, help="seconds between rows")
    parser.add_argument("--level", type=float, default=90.0, help="mean-class %% to reach")
    parser.add_argument("--out", type=Path, default=None, help="write every record as JSON")
    parser.add_argument("--plot", type=Path, default=None, help="draw every run's series (png)")
    args = parser.parse_args(argv)
    if args.every <= 0:
        parser.error(f"--every={args.every} must be > 0 seconds")
    register_configs()
    records = []
    with initialize_config_dir(config_dir=str(REPO_DIR / "conf"), version_base="1.3"):
        for run_dir in args.runs:
            if not all((run_dir / f).is_file() for f in ("metrics.json", "checkpoint.pt")):
                continue  # not a finished map run
            records.append(run_lag(run_dir, args.every, args.level))
            print(summary_line(records[-1]), flush=True)
    if not records:
        raise SystemExit("map_lag: no finished map run (metrics.json and checkpoint.pt) given")
    if args.out is not None:
        args.out.write_text(json.dumps(records, indent=1))
        print(f"wrote {args.out}")
    if args.plot is not None:
        print(f"wrote {plot_map_lag(records, args.plot)}")


if __name__ == "__main__":
    main()
