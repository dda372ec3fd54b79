"""Where a material map's errors come from: unpressed regions, missing or wrong labels, borders.

Each material region of the ground truth (a connected set of faces of one material, seams
and other ignored faces cutting regions apart) is judged by the touches that pressed it:

- `unpressed`: no touch pressed the region (fewer than `PRESS_SHARE` of a touch's contact
  points lie on it); the map can only guess there;
- `abstained`: pressed, but the classifier labelled none of its presses;
- `outvoted`: a press on it was labelled with its material, but the label vote left every
  such label out of the material loss;
- `mislabelled`: the classifier's labels there all name another material;
- `supported`: at least one label the map trained on names the region's material; the
  map's errors there are where it draws the border or extends a neighbour's label past
  the presses.

Every wrong ground-truth sample is charged to its region's case. Mean-class matching loses
100 / (k n_m) points per wrong sample of material m (k materials present, n_m samples of
m), so each case's share of the lost points is reported beside its share of wrong samples.
For the supported case the distance from each wrong sample to the nearest press that
carried its true label says how far the map extended a neighbour's label past them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.objects.proximity import closest_faces

CASES = ("unpressed", "abstained", "outvoted", "mislabelled", "supported")
PRESS_SHARE = 0.25  # of a touch's contact points on a region for the touch to press it
DISTANCE_BINS_M = (0.005, 0.01, 0.02, 0.04)  # supported errors by distance to a right press


@dataclass
class TouchSet:
    """Touches as the mapper stored them, object frame.

    points: per touch an (n_i, 3) array of contact points; labels: (T,) the touch's label
    (-1: none); used: (T,) whether the material loss trained on it (a label the vote left
    out is not used); point_labels: per touch (n_i,) labels of its points when they differ
    (patch readings), None: every point takes its touch's label; used_point_labels: per
    touch (n_i,) the labels the material loss trained on, -1 where the vote left a reading
    out (with patch readings the vote judges each material a touch reads on its own, so a
    used touch can still have a reading left out), None: `used` decides per touch.
    """

    points: list[np.ndarray]
    labels: np.ndarray
    used: np.ndarray
    point_labels: list[np.ndarray] | None = None
    used_point_labels: list[np.ndarray] | None = None

    def __post_init__(self) -> None:
        self.labels = np.asarray(self.labels, dtype=np.int64).reshape(-1)
        self.used = np.asarray(self.used, dtype=bool).reshape(-1)
        if not len(self.points) == len(self.labels) == len(self.used):
            raise ValueError(
                f"{len(self.points)} touches but {len(self.labels)} labels, {len(self.used)} flags"
            )
        if self.point_labels is not None and [len(p) for p in self.point_labels] != [
            len(p) for p in self.points
        ]:
            raise ValueError("point_labels must hold one label per contact point of each touch")
        if self.used_point_labels is not None and [len(p) for p in self.used_point_labels] != [
            len(p) for p in self.points
        ]:
            raise ValueError(
                "used_point_labels must hold one label per contact point of each touch"
            )

    def labels_of(self, t: int) -> np.ndarray:
        """(n_t,) labels of touch t's points."""
        if self.point_labels is not None:
            return np.asarray(self.point_labels[t], dtype=np.int64)
        return np.full(len(self.points[t]), self.labels[t], dtype=np.int64)

    def used_labels_of(self, t: int) -> np.ndarray:
        """(n_t,) labels of touch t's points that the material loss trained on (-1: not)."""
        if self.used_point_labels is not None:
            return np.asarray(self.used_point_labels[t], dtype=np.int64)
        if not self.used[t]:
            return np.full(len(self.points[t]), -1, dtype=np.int64)
        return self.labels_of(t)


def face_regions(obj: MaterialObject) -> np.ndarray:
    """(F,) region id per face: connected same-material faces share one; ignored faces -1."""
    labels = np.asarray(obj.face_labels)
    pairs = np.asarray(obj.mesh.face_adjacency)
    same = (labels[pairs[:, 0]] == labels[pairs[:, 1]]) & (labels[pairs[:, 0]] != IGNORE)
    pairs = pairs[same]
    n = len(labels)
    graph = scipy.sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, component = connected_components(graph, directed=False)
    regions = np.full(n, -1, dtype=np.int64)
    roi = labels != IGNORE
    _, regions[roi] = np.unique(component[roi], return_inverse=True)
    return regions


def _pressed_regions(
    obj: MaterialObject, regions: np.ndarray, touches: TouchSet
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per touch, the regions it pressed (at least PRESS_SHARE of its points on them) and
    the region under each of its points (-1: ignored faces)."""
    if not touches.points:
        return []
    sizes = [len(p) for p in touches.points]
    faces, _ = closest_faces(obj.mesh, np.concatenate(touches.points))
    per_touch = np.split(regions[faces], np.cumsum(sizes)[:-1])
    pressed = []
    for region, size in zip(per_touch, sizes):
        ids, counts = np.unique(region[region >= 0], return_counts=True)
        pressed.append((ids[counts >= PRESS_SHARE * size], region))
    return pressed


def region_cases(
    obj: MaterialObject, regions: np.ndarray, touches: TouchSet
) -> tuple[list[str], list[dict]]:
    """The case of each region (CASES) and its record: material, presses, labels."""
    count = int(regions.max()) + 1 if regions.size and regions.max() >= 0 else 0
    material = np.full(count, -1, dtype=np.int64)
    material[regions[regions >= 0]] = np.asarray(obj.face_labels)[regions >= 0]
    presses, labelled, right, right_used = (np.zeros(count, dtype=np.int64) for _ in range(4))
    for t, (ids, point_region) in enumerate(_pressed_regions(obj, regions, touches)):
        point_labels, used_labels = touches.labels_of(t), touches.used_labels_of(t)
        for r in ids:
            read = point_labels[point_region == r]
            presses[r] += 1
            labelled[r] += bool((read >= 0).any())
            right[r] += bool((read == material[r]).any())
            right_used[r] += bool((used_labels[point_region == r] == material[r]).any())
    cases = [
        "unpressed" if presses[r] == 0
        else "supported" if right_used[r] > 0
        else "outvoted" if right[r] > 0
        else "mislabelled" if labelled[r] > 0
        else "abstained"
        for r in range(count)
    ]  # fmt: skip
    records = [
        {
            "material": obj.class_names[int(material[r])],
            "case": cases[r],
            "touches": int(presses[r]),
            "labelled": int(labelled[r]),
            "right": int(right[r]),
            "right_used": int(right_used[r]),
        }
        for r in range(count)
    ]
    return cases, records


def error_sources(
    obj: MaterialObject,
    sample_points: np.ndarray,
    sample_faces: np.ndarray,
    predicted: np.ndarray,
    touches: TouchSet,
) -> dict:
    """Charge every wrong ground-truth sample to its region's case (see the module docstring).

    sample_points (N, 3) and sample_faces (N,): the matching samples and their faces (in the
    regions of interest); predicted (N,): the map's class there.
    """
    regions = face_regions(obj)
    cases, records = region_cases(obj, regions, touches)
    sample_region = regions[np.asarray(sample_faces)]
    if np.any(sample_region < 0):
        raise ValueError("error_sources: samples must lie on faces in the regions of interest")
    truth = np.asarray(obj.face_labels)[np.asarray(sample_faces)]
    wrong = np.asarray(predicted) != truth
    present, n_per = np.unique(truth, return_counts=True)
    lost_per_sample = np.zeros(len(truth))
    for m, n in zip(present, n_per):
        lost_per_sample[truth == m] = 100.0 / (len(present) * n)
    sample_case = np.array([cases[r] for r in sample_region])
    by_case = {}
    for case in CASES:
        mine = wrong & (sample_case == case)
        by_case[case] = {
            "wrong_samples": int(mine.sum()),
            "mean_class_points_lost": float(lost_per_sample[mine].sum()),
            "regions": sum(c == case for c in cases),
        }
    for r, record in enumerate(records):
        inside = sample_region == r
        record["area_share"] = float(inside.mean())
        record["recall_pct"] = float(100.0 * (1.0 - wrong[inside].mean())) if inside.any() else None
    return {
        "by_case": by_case,
        "wrong_samples": int(wrong.sum()),
        "mean_class_points_lost": float(lost_per_sample[wrong].sum()),
        "supported_distance_m": _supported_distances(
            sample_points, truth, wrong & (sample_case == "supported"), touches
        ),
        "regions": records,
    }


def _supported_distances(
    points: np.ndarray, truth: np.ndarray, chosen: np.ndarray, touches: TouchSet
) -> dict:
    """Wrong supported samples by distance to the nearest used press of their true material."""
    bins = [0.0, *DISTANCE_BINS_M, np.inf]
    counts = np.zeros(len(bins) - 1, dtype=np.int64)
    for m in np.unique(truth[chosen]):
        mine = chosen & (truth == m)
        ok = [p[touches.used_labels_of(t) == m] for t, p in enumerate(touches.points)]
        distance = cKDTree(np.concatenate(ok)).query(points[mine])[0]
        counts += np.histogram(distance, bins=bins)[0]
    names = [f"<{b * 100:g}cm" for b in DISTANCE_BINS_M] + [f">={DISTANCE_BINS_M[-1] * 100:g}cm"]
    return dict(zip(names, counts.tolist()))
