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
    edge = TouchLabel("index", True, label=2, confidence=0.95, weight=0.3)  # an edge imprint
    assert np.allclose(touch_point_labels(reading, points, world_T_object, edge)[1], 0.285)
    abstained = TouchLabel("index", True, low_confidence=True)
    assert (touch_point_labels(reading, points, world_T_object, abstained)[0] == -1).all()
    assert (touch_point_labels(reading, points, world_T_object, None)[0] == -1).all()


def _vote(min_support: int = 0) -> LabelVote:
    return LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=min_support,
                     press_gap=0, support_radius=0.04, steady_frames=0, press_reach=None)  # fmt: skip


AXIS = torch.tensor([0.0, 0.0, 1.0])


def test_each_material_a_touch_reads_is_voted_on_by_itself() -> None:
    touches = TouchBuffer(CPU, _vote())
    # A press across a border: fabric on x < 0, plastic on x > 0 (and one unread point).
    points = torch.tensor([[-0.004, 0, 0]] * 3 + [[0.004, 0, 0]] * 2 + [[0.0, 0, 0]])
    touches.add(points, AXIS, torch.tensor([2, 2, 2, 0, 0, -1]), torch.full((6,), 0.9))
    assert touches.tensors()["labelled_labels"].tolist() == [2, 2, 2, 0, 0]
    assert touches.num_labelled == 1 and touches.state_dict()["touch_labels"] == [2]
    # Three presses read plastic 8 mm from the fabric side's centroid: they outvote the
    # fabric reading and back the plastic one; the touch keeps its plastic points.
    for _ in range(3):
        touches.add(torch.full((2, 3), 0.0) + torch.tensor([0.004, 0, 0]), AXIS, 0, 0.9)
    assert touches.num_outvoted == 1
    kept = touches.point_labels_used()
    assert kept[0].tolist() == [-1, -1, -1, 0, 0, -1]
    assert touches.outvoted().tolist() == [False, False, False, False]
    assert touches.tensors()["labelled_labels"].tolist() == [0] * 8
    # A stray reading on fewer than a tenth of a touch's points is not a reading at all.
    stray = TouchBuffer(CPU, _vote())
    stray.add(torch.zeros(20, 3), AXIS, torch.tensor([0] * 19 + [2]), torch.ones(20))
    assert stray.tensors()["labelled_labels"].tolist() == [0] * 19
    unlabelled = TouchBuffer(CPU)
    unlabelled.add(torch.zeros(3, 3), AXIS, torch.tensor([-1, -1, -1]), torch.zeros(3))
    assert unlabelled.num_labelled == 0 and unlabelled.state_dict()["touch_labels"] == [-1]
    restored = TouchBuffer(CPU, _vote())
    state = touches.state_dict()
    del state["touch_labels"]  # a checkpoint from before patch readings
    restored.load_state_dict(state)
    assert restored.num_outvoted == 1


def test_a_press_that_grazes_an_insert_backs_the_inserts_own_press() -> None:
    from neuralfeels_sem.mapping.touch_memory import materials_read

    assert materials_read(torch.tensor([0] * 9 + [2] + [-1] * 5)) == (0, 2)  # 1 of 10: 10 %
    assert materials_read(torch.tensor([0] * 19 + [2])) == (0,)  # a stray 5 % does not count
    assert materials_read(torch.tensor([-1, -1])) == ()
    touches = TouchBuffer(CPU, _vote(min_support=1))
    touches.add(torch.zeros(4, 3), AXIS, 2, 0.9)  # the insert's own press: fabric
    touches.add(torch.full((4, 3), 0.02), AXIS, 0, 0.9)  # plastic around it
    touches.add(torch.full((4, 3), 0.021), AXIS, 0, 0.9)
    assert touches.outvoted().tolist() == [True, False, False]  # nobody else read fabric
    grazing = torch.tensor([[0.015, 0.0, 0.0]] * 3 + [[0.008, 0.0, 0.0]])
    touches.add(grazing, AXIS, torch.tensor([0, 0, 0, 2]), torch.ones(4))
    assert touches.outvoted().tolist() == [False, False, False, False]
    assert touches.point_labels_used()[3].tolist() == [0, 0, 0, 2]


def test_a_geometry_only_touch_does_not_join_two_presses() -> None:
    # A finger reads fabric at frames 0 and 6 and abstains at frame 3: with a press gap of
    # 4 frames the two readings are two presses that back each other. Chaining presses
    # over the abstained touch would make them one press that backs nobody.
    vote = LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=1,
                     press_gap=4, support_radius=0.04, steady_frames=0, press_reach=None)  # fmt: skip
    touches = TouchBuffer(CPU, vote)
    for frame in range(7):  # every frame mapped, as at sensor.pace=offline
        touches.note_frame(frame)
    touches.add(torch.zeros(4, 3), AXIS, 2, 0.9, finger="index", frame_index=0)
    touches.add(torch.zeros(4, 3), AXIS, -1, 0.0, finger="index", frame_index=3)
    touches.add(torch.full((4, 3), 0.002), AXIS, 2, 0.9, finger="index", frame_index=6)
    assert touches.outvoted().tolist() == [False, False, False]
    assert touches.num_outvoted == 0


def test_a_lone_left_out_reading_awaits_a_second_press_until_one_comes_near() -> None:
    touches = TouchBuffer(CPU, _vote(min_support=1))
    touches.add(torch.zeros(4, 3), AXIS, 2, 0.9, finger="thumb", frame_index=0)  # fabric, once
    far = torch.full((4, 3), 0.05)
    touches.add(far, AXIS, 0, 0.9, finger="index", frame_index=0)
    touches.add(far + 0.001, AXIS, 0, 0.9, finger="index", frame_index=9)
    np.testing.assert_allclose(touches.unconfirmed_readings(0.01).numpy(), [[0.0, 0.0, 0.0]])
    assert len(TouchBuffer(CPU).unconfirmed_readings(0.01)) == 0  # no vote, nothing left out
    # A second press near it reads plastic: the fabric reading stays out, but is settled.
    touches.add(torch.full((4, 3), 0.004), AXIS, 0, 0.9, finger="middle", frame_index=12)
    assert touches.outvoted().tolist()[0] and len(touches.unconfirmed_readings(0.01)) == 0
    # Or it reads fabric: the two back each other and nothing is left out.
    agreed = TouchBuffer(CPU, _vote(min_support=1))
    agreed.add(torch.zeros(4, 3), AXIS, 2, 0.9, finger="thumb", frame_index=0)
    agreed.add(torch.full((4, 3), 0.004), AXIS, 2, 0.9, finger="middle", frame_index=12)
    assert not any(agreed.outvoted().tolist()) and len(agreed.unconfirmed_readings(0.01)) == 0
