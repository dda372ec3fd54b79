"""Per-point labels of a touch: patch readings follow each contact point back to its pixel."""

from __future__ import annotations

import numpy as np
import torch

from neuralfeels_sem.core.digit import DIGIT_HEIGHT, DIGIT_INTRINSICS, DIGIT_WIDTH
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.mapping.label_vote import LabelVote
from neuralfeels_sem.mapping.memory import touch_point_labels
from neuralfeels_sem.mapping.touch_memory import TouchBuffer
from neuralfeels_sem.perception.pointcloud import tactile_points
from neuralfeels_sem.perception.touch import NO_LABEL, TouchLabel

CPU = torch.device("cpu")


def _pose(angle: float, shift) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = shift
    return pose


def test_each_contact_point_takes_the_label_of_the_pixel_it_came_from() -> None:
    v, u = np.mgrid[0:DIGIT_HEIGHT, 0:DIGIT_WIDTH]
    contact = (v - 160) ** 2 + (u - 120) ** 2 <= 90**2
    depth = np.where(contact, 0.0195 + 1e-5 * np.sin(u / 7.0), 0.0)  # a slightly wavy press
    reading = TactileReading(
        "index", np.zeros((DIGIT_HEIGHT, DIGIT_WIDTH, 3), np.uint8),
        _pose(0.3, [0.01, -0.02, 0.1]), DIGIT_INTRINSICS,
    )  # fmt: skip
    world_T_object = _pose(-0.7, [0.002, 0.03, 0.08])
    points = tactile_points(reading, depth, world_T_object)
    rows, cols = np.nonzero(depth > 0)  # the order backproject keeps
    left_right = np.where(u < 120, 0, 2).astype(np.int16)
    left_right[v > 200] = NO_LABEL  # the bottom patch abstained
    confidence = np.where(u < 120, 0.9, 0.8).astype(np.float32)
    label = TouchLabel("index", True, label=0, confidence=0.9, pixel_labels=left_right,
                       pixel_confidence=confidence)  # fmt: skip
    labels, weights = touch_point_labels(reading, points, world_T_object, label)
    np.testing.assert_array_equal(labels, left_right[rows, cols])
    np.testing.assert_allclose(weights, confidence[rows, cols])
    # Without patch readings: the touch's label on every point, or none.
    plain = TouchLabel("index", True, label=2, confidence=0.95)
    labels, weights = touch_point_labels(reading, points, world_T_object, plain)
    assert (labels == 2).all() and np.allclose(weights, 0.95)
    abstained = TouchLabel("index", True, low_confidence=True)
    assert (touch_point_labels(reading, points, world_T_object, abstained)[0] == -1).all()
    assert (touch_point_labels(reading, points, world_T_object, None)[0] == -1).all()


def test_a_touch_with_point_labels_trains_its_labelled_points_and_votes_by_its_mode() -> None:
    vote = LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=0,
                     press_gap=0, support_radius=None)  # fmt: skip
    touches = TouchBuffer(CPU, vote)
    axis = torch.tensor([0.0, 0.0, 1.0])
    mixed = torch.tensor([2, 2, 2, 0, 0, -1])
    touches.add(torch.zeros(6, 3), axis, mixed, torch.full((6,), 0.9))
    tensors = touches.tensors()
    assert tensors["labelled_labels"].tolist() == [2, 2, 2, 0, 0]
    assert touches.num_labelled == 1 and touches.state_dict()["touch_labels"] == [2]
    # Three neighbours read 0: the mixed touch's vote label (2) is outvoted, all its points go.
    for _ in range(3):
        touches.add(torch.full((2, 3), 0.001), axis, 0, 0.9)
    assert touches.num_outvoted == 1
    assert touches.tensors()["labelled_labels"].tolist() == [0, 0, 0, 0, 0, 0]
    unlabelled = TouchBuffer(CPU)
    unlabelled.add(torch.zeros(3, 3), axis, torch.tensor([-1, -1, -1]), torch.zeros(3))
    assert unlabelled.num_labelled == 0 and unlabelled.state_dict()["touch_labels"] == [-1]
    restored = TouchBuffer(CPU, vote)
    state = touches.state_dict()
    del state["touch_labels"]  # a checkpoint from before patch readings
    restored.load_state_dict(state)
    assert restored.num_outvoted == 1


def test_a_neighbour_that_reads_a_material_in_some_patches_backs_a_lone_touch_of_it() -> None:
    from neuralfeels_sem.mapping.label_vote import outvoted_touches
    from neuralfeels_sem.mapping.touch_memory import materials_read

    c = torch.tensor([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0]])
    labels = torch.tensor([2, 0])  # a lone fabric press; a plastic press 2 cm away
    assert outvoted_touches(c, labels, 0.01, 3, 0.25, min_support=1, support_radius=0.04)[0]
    reads = torch.tensor([[False, False, True], [True, False, True]])  # it read fabric too
    kept = outvoted_touches(c, labels, 0.01, 3, 0.25, 1, None, 0.04, reads)
    assert kept.tolist() == [False, True]  # no other press backs the plastic one
    assert materials_read(torch.tensor([0] * 9 + [2] + [-1] * 5)) == (0, 2)  # 1 of 10: 10 %
    assert materials_read(torch.tensor([0] * 19 + [2])) == (0,)  # a stray 5 % does not count
    assert materials_read(torch.tensor([-1, -1])) == ()
    vote = LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=1,
                     press_gap=0, support_radius=0.04)  # fmt: skip
    axis = torch.tensor([0.0, 0.0, 1.0])
    touches = TouchBuffer(CPU, vote)
    touches.add(torch.zeros(4, 3), axis, 2, 0.9)
    touches.add(torch.full((4, 3), 0.02), axis, 0, 0.9)
    touches.add(torch.full((4, 3), 0.021), axis, 0, 0.9)
    assert touches.outvoted().tolist() == [True, False, False]
    touches.add(torch.full((4, 3), 0.019), axis, torch.tensor([0, 0, 0, 2]), torch.ones(4))
    assert touches.outvoted().tolist() == [False, False, False, False]
