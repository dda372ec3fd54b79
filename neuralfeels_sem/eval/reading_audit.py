"""What became of a run's touch readings, and how right each kind was (needs ground truth).

A low material map raises three questions that the touches the mapper stored answer:

- per material: how many frames read it rightly, and how many of those the map trained
  on. A material read rightly in one frame or none gets next to no recall in the map;
  the label vote leaves a lone reading out, as it must (most lone readings are wrong);
- the readings the label vote left out: how many named their true material;
- the presses the classifier abstained on (imprint at the sensor's edge, or below its
  confidence): how often their top class was right, by confidence, and how often when it
  names a material the kept labels (nearly) lack.

A reading is one material one touch (one finger, one frame) read: a touch across a border
read by patch readings is one reading per material. It is right when that material is the
majority ground truth under the points that read it. The caller gathers the touches
(bench/map_errors.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from neuralfeels_sem.eval.error_sources import TouchSet
from neuralfeels_sem.mapping.touch_memory import materials_read
from neuralfeels_sem.objects.material_object import MaterialObject

CONFIDENCE_EDGES = (0.0, 0.9, 0.99, 0.999, 0.9999, 1.0)  # bins of the top-class probability
RARE_KEPT = 10  # a material with fewer kept readings than this is one the map nearly lacks
RARE_MIN_CONFIDENCE = 0.99  # abstained readings judged as naming a rare material


@dataclass
class Abstentions:
    """Presses the classifier abstained on: per press its (n_i, 3) contact points (object
    frame), (A, C) class probabilities and (A,) whether it abstained for the sensor's edge
    (else: below its confidence)."""

    points: list[np.ndarray]
    probs: np.ndarray
    at_edge: np.ndarray

    def __post_init__(self) -> None:
        probs = np.asarray(self.probs, np.float64)
        self.probs = probs if probs.size else np.zeros((0, 0))
        if self.probs.ndim != 2 or len(self.probs) != len(self.points):
            raise ValueError(f"{len(self.points)} abstained presses, {len(self.probs)} readings")
        self.at_edge = np.asarray(self.at_edge, bool).reshape(-1)
        if len(self.at_edge) != len(self.points):
            raise ValueError(f"{len(self.points)} abstained presses, {len(self.at_edge)} flags")


def majority_truth(obj: MaterialObject, points: np.ndarray) -> int:
    """The most common true material under the points (-1 where all are ignored)."""
    return _majority(obj.labels_at(np.asarray(points, np.float64).reshape(-1, 3)))


def readings(obj: MaterialObject, touches: TouchSet) -> list[tuple[int, int, bool]]:
    """(material read, its majority truth, kept by the vote) for every reading: each
    material the mapper counts as read by a touch (touch_memory.materials_read)."""
    out = []
    for t, points in enumerate(touches.points):
        read, used = touches.labels_of(t), touches.used_labels_of(t)
        truth = obj.labels_at(points) if (read >= 0).any() else None
        for material in materials_read(torch.as_tensor(read)):
            mine = read == material
            out.append((material, _majority(truth[mine]), bool((used[mine] >= 0).any())))
    return out


def per_material(
    found: list[tuple[int, int, bool]], class_names: list[str], recall: dict | None = None
) -> dict:
    """Per material: frames that read it rightly, those the map kept, frames that named it
    wrongly, and (given the run's per-class matching) its recall in the map."""
    out = {}
    for m, name in enumerate(class_names):
        right = [kept for read, truth, kept in found if read == m and truth == m]
        out[name] = {
            "frames_right": len(right),
            "frames_right_kept": int(sum(right)),
            "frames_naming_it_wrongly": sum(1 for r, t, _ in found if r == m and t not in (m, -1)),
            "map_recall_pct": None if recall is None else recall.get(name),
        }
    return out


def outvoted(found: list[tuple[int, int, bool]]) -> dict:
    """The readings the label vote left out, and how many named their true material."""
    judged = [(read, truth) for read, truth, kept in found if not kept and truth >= 0]
    right = sum(1 for read, truth in judged if read == truth)
    return {"readings": len(judged), "right": right, "right_pct": _pct(right, len(judged))}


def abstained_by_confidence(obj: MaterialObject, abstained: Abstentions) -> dict:
    """Per reason (`edge`, `low_confidence`) and confidence bin: frames, top class right."""
    truth = np.array([majority_truth(obj, p) for p in abstained.points], dtype=np.int64)
    top, confidence = _top(abstained)
    last = len(CONFIDENCE_EDGES) - 2  # the top bin includes 1.0 itself
    bin_of = np.minimum(np.searchsorted(CONFIDENCE_EDGES, confidence, side="right") - 1, last)
    out = {}
    for reason, mask in (("edge", abstained.at_edge), ("low_confidence", ~abstained.at_edge)):
        rows = []
        for k, (lo, hi) in enumerate(zip(CONFIDENCE_EDGES[:-1], CONFIDENCE_EDGES[1:])):
            inside = mask & (truth >= 0) & (bin_of == k)
            frames, right = int(inside.sum()), int((top[inside] == truth[inside]).sum())
            rows.append({"from": lo, "to": hi, "frames": frames, "right": right})
            rows[-1]["right_pct"] = _pct(right, frames)
        out[reason] = rows
    return out


def abstained_rare(
    obj: MaterialObject, abstained: Abstentions, found: list[tuple[int, int, bool]]
) -> dict:
    """Confident abstained readings (>= RARE_MIN_CONFIDENCE) naming a material the map kept
    fewer than RARE_KEPT readings of: the ones a planner might send a finger back for."""
    top, confidence = _top(abstained)
    kept = np.bincount([read for read, _, k in found if k], minlength=abstained.probs.shape[1])
    rare = (confidence >= RARE_MIN_CONFIDENCE) & (kept[top] < RARE_KEPT)
    truth = [majority_truth(obj, abstained.points[i]) for i in np.flatnonzero(rare)]
    judged = [(int(top[i]), t) for i, t in zip(np.flatnonzero(rare), truth) if t >= 0]
    right = sum(1 for read, t in judged if read == t)
    return {"frames": len(judged), "right": right, "right_pct": _pct(right, len(judged))}


def reading_audit(
    obj: MaterialObject,
    touches: TouchSet,
    abstained: Abstentions,
    class_names: list[str],
    recall: dict | None = None,
) -> dict:
    """All four parts of the audit for one run (see the module docstring)."""
    found = readings(obj, touches)
    return {
        "per_material": per_material(found, class_names, recall),
        "outvoted": outvoted(found),
        "abstained_by_confidence": abstained_by_confidence(obj, abstained),
        "abstained_rare_material": abstained_rare(obj, abstained, found),
    }


FRAMES_RIGHT_BINS = ((0, 1), (2, 4), (5, 9), (10, None))  # materials by frames read rightly


def pool_audits(audits: list[dict]) -> dict:
    """Several runs' audits pooled: materials by frames read rightly (count, mean recall in
    the map, of those present whose recall is known), and the summed counts of the rest."""
    rows_of = (audit["per_material"].values() for audit in audits)
    materials = [row for rows in rows_of for row in rows if row["map_recall_pct"] is not None]
    by_frames = []
    for lo, hi in FRAMES_RIGHT_BINS:
        rows = [
            r
            for r in materials
            if lo <= r["frames_right"] and (hi is None or r["frames_right"] <= hi)
        ]
        recall = float(np.mean([r["map_recall_pct"] for r in rows])) if rows else None
        by_frames.append({"from": lo, "to": hi, "materials": len(rows), "mean_recall_pct": recall})
    outvoted_sum = {k: sum(a["outvoted"][k] for a in audits) for k in ("readings", "right")}
    rare = {k: sum(a["abstained_rare_material"][k] for a in audits) for k in ("frames", "right")}
    bins = {reason: _summed_bins(audits, reason) for reason in ("edge", "low_confidence")}
    return {
        "materials_by_frames_right": by_frames,
        "outvoted": {
            **outvoted_sum,
            "right_pct": _pct(outvoted_sum["right"], outvoted_sum["readings"]),
        },
        "abstained_by_confidence": bins,
        "abstained_rare_material": {**rare, "right_pct": _pct(rare["right"], rare["frames"])},
    }


def _majority(truth: np.ndarray) -> int:
    """The most common of these true materials, ignored faces (-1) left out (-1: none)."""
    truth = truth[truth >= 0]
    return int(np.bincount(truth).argmax()) if len(truth) else -1


def _summed_bins(audits: list[dict], reason: str) -> list[dict]:
    """One reason's confidence bins, frames and right answers summed over the audits."""
    if not audits:
        return []
    rows = []
    for k, row in enumerate(audits[0]["abstained_by_confidence"][reason]):
        frames = sum(a["abstained_by_confidence"][reason][k]["frames"] for a in audits)
        right = sum(a["abstained_by_confidence"][reason][k]["right"] for a in audits)
        rows.append({**row, "frames": frames, "right": right, "right_pct": _pct(right, frames)})
    return rows


def _top(abstained: Abstentions) -> tuple[np.ndarray, np.ndarray]:
    """(A,) top class and its probability of every abstained press (empty without any)."""
    if not len(abstained.points):
        return np.zeros(0, np.int64), np.zeros(0)
    return abstained.probs.argmax(1), abstained.probs.max(1)


def _pct(part: int, whole: int) -> float | None:
    return None if whole == 0 else 100.0 * part / whole
