"""Accuracy of the tactile material classifier during a run, against the simulator's ground truth.

Each update is one classified touch: the predicted class (or NO_LABEL = -1 when the
classifier abstained: no contact seen or confidence below threshold) and the ground-truth
class under the contact (None when the simulator reports no contact or no material).
Three figures per finger, per material and per finger x material, over the touches that
have a ground truth:
- `accuracy`: correct / judged (touches that got a label): how far a label can be trusted;
- `coverage`: judged / touches: how often a touch gave the map a label at all;
- `accuracy_all_touches`: correct / touches (an abstention counts as not correctly
  labelled): what the map actually received, so a finger that rarely commits shows it.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence

import numpy as np

from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.objects.material_object import IGNORE
from neuralfeels_sem.perception.touch import NO_LABEL

MIN_LABELLED_SHARE = 0.5  # of the contact pixels, for a touch to have a ground truth


def gt_material_of(reading: TactileReading) -> int | None:
    """Majority ground-truth class over the contact pixels.

    None without contact, or when less than MIN_LABELLED_SHARE of the contact lies in the
    regions of interest: a press on an ignored face (an object's bottom) is not judged by
    the few labelled pixels at its rim.
    """
    if reading.gt_material is None or reading.gt_contact_mask is None:
        return None
    material = np.asarray(reading.gt_material)[np.asarray(reading.gt_contact_mask, dtype=bool)]
    contact_px = material.size
    material = material[material != IGNORE]
    if material.size == 0 or material.size < MIN_LABELLED_SHARE * contact_px:
        return None
    values, counts = np.unique(material.astype(np.int64), return_counts=True)
    return int(values[counts.argmax()])  # ties go to the lower class index


class ClassifierAccuracy:
    """Running tallies of classified touches per finger and ground-truth material."""

    def __init__(self) -> None:
        # (finger, gt) -> [correct, wrong, abstained]
        self._tally: dict[tuple[str, int], list[int]] = defaultdict(lambda: [0, 0, 0])
        self.no_ground_truth: dict[str, int] = defaultdict(int)

    def update(self, finger: str, predicted: int, gt: int | None) -> None:
        if gt is None:
            self.no_ground_truth[finger] += 1
            return
        if gt < 0:
            raise ValueError(f"ground-truth class {gt} must be >= 0 (use None for no ground truth)")
        tally = self._tally[(finger, int(gt))]
        if predicted == NO_LABEL:
            tally[2] += 1
        elif predicted < 0:
            raise ValueError(f"predicted class {predicted} must be >= 0 or NO_LABEL ({NO_LABEL})")
        else:
            tally[0 if int(predicted) == int(gt) else 1] += 1

    @staticmethod
    def _stats(tallies: list[list[int]]) -> dict:
        correct = sum(t[0] for t in tallies)
        wrong = sum(t[1] for t in tallies)
        abstained = sum(t[2] for t in tallies)
        judged = correct + wrong
        touches = judged + abstained
        return {
            "accuracy": correct / judged if judged else None,
            "coverage": judged / touches if touches else None,
            "accuracy_all_touches": correct / touches if touches else None,
            "correct": correct,
            "judged": judged,
            "abstentions": abstained,
            "touches": touches,
        }

    def summary(self, class_names: Sequence[str]) -> dict:
        """Accuracies in 0-1 (None where nothing was judged) with their counts.

        Keys: overall, coverage, accuracy_all_touches; per_finger {finger: acc},
        per_material {name: acc}, per_finger_material {finger: {name: acc}}; by_finger and
        by_material {name: every figure and count of `_stats`}; counts {finger: {name: {...}}};
        abstentions (total), abstention_rate (abstained / touches with ground truth), no_ground_truth.
        """
        for _, gt in self._tally:
            if gt >= len(class_names):
                raise ValueError(f"ground-truth class {gt} outside class_names {list(class_names)}")
        fingers = sorted({f for f, _ in self._tally})
        materials = sorted({g for _, g in self._tally})
        overall = self._stats(list(self._tally.values()))
        out: dict = {
            "overall": overall["accuracy"],
            "coverage": overall["coverage"],
            "accuracy_all_touches": overall["accuracy_all_touches"],
            "per_finger": {},
            "per_material": {},
            "per_finger_material": {},
            "by_finger": {},
            "by_material": {},
            "counts": {},
            "abstentions": overall["abstentions"],
            "abstention_rate": (
                overall["abstentions"] / (overall["judged"] + overall["abstentions"])
                if overall["judged"] + overall["abstentions"]
                else None
            ),
            "judged": overall["judged"],
            "no_ground_truth": dict(self.no_ground_truth),
        }
        for finger in fingers:
            stats = self._stats([t for (f, _), t in self._tally.items() if f == finger])
            out["by_finger"][finger] = stats
            out["per_finger"][finger] = stats["accuracy"]
            out["per_finger_material"][finger] = {}
            out["counts"][finger] = {}
            for gt in materials:
                if (finger, gt) in self._tally:
                    stats = self._stats([self._tally[(finger, gt)]])
                    out["per_finger_material"][finger][class_names[gt]] = stats["accuracy"]
                    out["counts"][finger][class_names[gt]] = stats
        for gt in materials:
            stats = self._stats([t for (_, g), t in self._tally.items() if g == gt])
            out["by_material"][class_names[gt]] = stats
            out["per_material"][class_names[gt]] = stats["accuracy"]
        return out


def never_read(accuracy: Mapping, present: Sequence[str] | None) -> dict[str, str] | None:
    """{material: why} for the materials in `present` (the ground truth's) that no touch
    read rightly by its own label, in order of the first that holds:

    - "never pressed": no touch had most of its contact on the material, so no finger
      pressed a part of it squarely (the gait never reached it, or only its rim);
    - "never labelled": pressed, but the classifier abstained on every such touch;
    - "never read rightly": labelled, but always as another material.

    `accuracy` is `ClassifierAccuracy.summary`'s. A touch's label is its imprint's main
    reading: a press that reads a material on part of its imprint can still teach the map
    it, so such a material is not always lost (read this beside the map's recall of it).
    None where there is nothing to judge: no touch had a ground truth (a real rig, or no
    touches), or no material is present (no matching samples).
    """
    by_material = accuracy.get("by_material")
    if not present or by_material is None:
        return None
    if not accuracy.get("judged", 0) + accuracy.get("abstentions", 0):
        return None
    out = {}
    for name in present:
        stats = by_material.get(name) or {}
        if not stats.get("touches"):
            out[name] = "never pressed"
        elif not stats.get("judged"):
            out[name] = "never labelled"
        elif not stats.get("correct"):
            out[name] = "never read rightly"
    return out
