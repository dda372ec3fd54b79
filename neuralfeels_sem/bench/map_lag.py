"""How soon a finished run's material map was right, against how soon its touches allowed.

Reads each run directory's config, final checkpoint and matching curve (nothing is
re-run). Every `--every` seconds of sensor time (the latest curve point by then) and at
the run's end it sets the field's own mean-class matching (the run's curve) beside two
maps built from the touches made by then, each a nearest-point map on the run's matching
samples (a sample takes the label of the nearest contact point):
- `readings`: the classifier's labels of those touches (abstentions left out, the label
  vote not applied): what the readings so far support;
- `placement`: the true material of every contact point so far, read or not (an oracle
  of the simulator): what the places pressed allow with perfect reading.
The sensor time at which each first reaches `--level` tells what holds a run back: a
field that reaches it long after `readings` learns or extrapolates slower than its
touches allow; a late `placement` means the fingers had not yet pressed enough of the
object (where the object turned them and where the touch policy put them).

    python -m neuralfeels_sem.bench.map_lag multirun/sweep/* --out lag.json --plot lag.png
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
from neuralfeels_sem.eval.matching import MatchingEvaluator
from neuralfeels_sem.mapping.checkpoint import load_checkpoint
from neuralfeels_sem.tasks.build import BOUND_MARGIN, build_mapper, model_config
from neuralfeels_sem.tasks.eval import load_run_config
from neuralfeels_sem.utils.paths import REPO_DIR
from neuralfeels_sem.viz.lag_plot import plot_map_lag

SERIES = ("field", "readings", "placement")


def touch_history(mapper) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """The mapper's touches in arrival order: contact points (object frame), the
    classifier's label of each point (-1: abstained or geometry only), frame index."""
    state = mapper.memory.touches.state_dict()
    points = [p.cpu().numpy().astype(np.float64) for p in state["points"]]
    labels = [t.cpu().numpy().astype(np.int64) for t in state["labels"]]
    return points, labels, np.asarray(state["frames"], dtype=np.int64)


def maps_at(
    matching: MatchingEvaluator,
    points: list[np.ndarray],
    read: list[np.ndarray],
    truth: list[np.ndarray],
) -> dict[str, float | None]:
    """Mean-class matching of the `readings` and `placement` maps of these touches (per
    touch: contact points, the classifier's label and the true material of each point)."""
    out: dict[str, float | None] = {"readings": None, "placement": None}
    if not points:
        return out
    every = np.concatenate(points)
    for key, labels in (("readings", np.concatenate(read)), ("placement", np.concatenate(truth))):
        if (labels >= 0).any():
            scores = matching.nearest_scores(every[labels >= 0], labels[labels >= 0])
            out[key] = scores["matching_mean_class_pct"]
    return out


def lag_rows(
    obj,
    matching: MatchingEvaluator,
    history: tuple[list[np.ndarray], list[np.ndarray], np.ndarray],
    curve: list[list[float]],
    every_s: float,
) -> list[dict]:
    """Rows (time, frame and the three series) at the curve's points, every `every_s` of
    sensor time: at each multiple of it, the latest curve point not after it."""
    if every_s <= 0:
        raise ValueError(f"--every={every_s} must be > 0 seconds")
    points, labels, frames = history
    # The true material of every contact point, once: the closest-face query is the cost.
    sizes = np.cumsum([len(p) for p in points])[:-1]
    truth = np.split(obj.labels_at(np.concatenate(points)), sizes) if points else []
    rows = []
    for frame, time_s, field_pct in sampled(curve, every_s):
        made = np.flatnonzero(frames <= frame).tolist()
        row = {"time_s": float(time_s), "frame": int(frame), "field": float(field_pct)}
        pick = [points[t] for t in made], [labels[t] for t in made], [truth[t] for t in made]
        row.update(maps_at(matching, *pick))
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
    cfg = load_run_config(run_dir)
    obj = instantiate(cfg.object)
    mapper = build_mapper(cfg, BOUND_MARGIN * obj.bounds_radius, torch.device("cpu"))
    load_checkpoint(run_dir / "checkpoint.pt", mapper, model_config(cfg))
    matching = MatchingEvaluator(obj, int(cfg.eval.num_surface_samples), int(cfg.eval.seed))
    metrics = json.loads((run_dir / "metrics.json").read_text())
    rows = lag_rows(
        obj,
        matching,
        touch_history(mapper),
        metrics.get("matching_mean_class_curve") or [],
        every_s,
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
