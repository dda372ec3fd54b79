"""Press fusion: abstained touches labelled from the presses around them."""

from __future__ import annotations

import pytest
import torch

from neuralfeels_sem.mapping.mapper import MapperConfig
from neuralfeels_sem.mapping.press_fusion import PROB_FLOOR, PressFusion
from neuralfeels_sem.mapping.touch_memory import TouchBuffer

CPU = torch.device("cpu")
AXIS = torch.tensor([0.0, 0.0, 1.0])


def _fusion(**kw) -> PressFusion:
    settings = dict(
        radius=0.01, min_presses=2, confidence=0.9, weight=1.0, include_edge=False, press_gap=2
    )
    return PressFusion(**{**settings, **kw})


def _probs(*rows) -> torch.Tensor:
    return torch.tensor(rows, dtype=torch.float32)


def test_two_unsure_presses_that_agree_are_sure_together() -> None:
    centroids = torch.tensor([[0.0, 0.0, 0.0], [0.004, 0.0, 0.0], [0.05, 0.0, 0.0]])
    probs = _probs([0.1, 0.7, 0.2], [0.15, 0.7, 0.15], [0.1, 0.7, 0.2])
    labels, top = _fusion().fuse(centroids, probs, torch.tensor([0, 1, 2]), torch.tensor([0, 2]))
    # Naive Bayes over the two near presses: 0.49 / (0.01 + 0.015 + 0.49 + 0.03).
    assert labels.tolist() == [1, -1]  # the far one has only its own press
    assert top[0].item() == pytest.approx(0.49 / (0.1 * 0.15 + 0.49 + 0.2 * 0.15), rel=1e-5)
    assert top[1].item() == 0.0


def test_the_frames_of_one_press_count_once() -> None:
    centroids = torch.zeros(3, 3)
    probs = _probs([0.3, 0.7], [0.3, 0.7], [0.3, 0.7])
    one_press = _fusion().fuse(centroids, probs, torch.tensor([4, 4, 4]), torch.tensor([0]))
    assert one_press[0].tolist() == [-1]
    two = _fusion(confidence=0.8).fuse(centroids, probs, torch.tensor([4, 4, 9]), torch.tensor([0]))
    assert two[0].tolist() == [1] and two[1][0].item() == pytest.approx(0.49 / 0.58, rel=1e-5)


def test_disagreeing_presses_leave_it_unlabelled_and_a_saturated_one_cannot_veto() -> None:
    centroids = torch.zeros(3, 3)
    split = _fusion().fuse(centroids[:2], _probs([0.3, 0.7], [0.7, 0.3]), torch.tensor([0, 1]),
                           torch.tensor([0]))  # fmt: skip
    assert split[0].tolist() == [-1]
    probs = _probs([0.02, 0.98], [0.02, 0.98], [1.0, 0.0])
    unsure = _fusion(confidence=0.7)
    labels, top = unsure.fuse(centroids, probs, torch.tensor([0, 1, 2]), torch.tensor([2]))
    odds = 0.98**2 * PROB_FLOOR / (0.02**2 * 1.0)  # 2.4: the two presses outweigh the veto
    assert labels.tolist() == [1] and top[0].item() == pytest.approx(odds / (1 + odds), rel=1e-4)


def test_bad_settings_and_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="fuse_min_presses"):
        _fusion(min_presses=1)
    with pytest.raises(ValueError, match="fuse_confidence"):
        _fusion(confidence=0.0)
    with pytest.raises(ValueError, match="fuse_radius"):
        MapperConfig(fuse_radius=-0.01)
    with pytest.raises(ValueError, match="press ids"):
        _fusion().fuse(
            torch.zeros(2, 3), _probs([1.0], [1.0]), torch.tensor([0]), torch.tensor([0])
        )
    assert not MapperConfig().fuse_radius and not PressFusion.from_config(MapperConfig()).active


def _press(buffer: TouchBuffer, x: float, probs, finger: str, frame: int, **kw) -> None:
    points = torch.tensor([[x, 0.0, 0.0], [x + 0.001, 0.0, 0.0]])
    label = kw.pop("label", -1)
    weight = 0.9 if label >= 0 else 0.0
    buffer.add(points, AXIS, label, weight, finger=finger, frame_index=frame,
               probs=torch.tensor(probs), **kw)  # fmt: skip


def test_the_buffer_labels_abstained_touches_once_their_presses_agree() -> None:
    buffer = TouchBuffer(CPU, fusion=_fusion())
    _press(buffer, 0.0, [0.25, 0.75], "index", 0)
    assert buffer.num_labelled == 0  # one press: the classifier's abstention stands
    _press(buffer, 0.002, [0.3, 0.7], "index", 1)  # the same press, a frame later
    assert buffer.num_labelled == 0
    _press(buffer, 0.003, [0.9, 0.1], "thumb", 1, at_edge=True)  # an edge strip: not pooled
    _press(buffer, 0.003, [0.2, 0.8], "middle", 8)
    assert buffer.num_labelled == buffer.num_fused == 3 and buffer.num_touches == 4
    used = buffer.point_labels_used()
    assert [u.tolist() for u in used] == [[1, 1], [1, 1], [-1, -1], [1, 1]]
    weights = buffer.tensors()["labelled_weights"]
    assert torch.all(weights > 0.9) and torch.all(weights < 1.0)
    # A checkpoint keeps the fused labels, the readings and the count.
    restored = TouchBuffer(CPU, fusion=_fusion())
    restored.load_state_dict(buffer.state_dict())
    assert restored.num_fused == 3 and restored._at_edge == [False, False, True, False]
    assert [u.tolist() for u in restored.point_labels_used()] == [u.tolist() for u in used]


def test_with_edge_touches_pooled_a_labelled_neighbour_counts_as_evidence() -> None:
    buffer = TouchBuffer(CPU, fusion=_fusion(include_edge=True, confidence=0.95))
    _press(buffer, 0.0, [0.05, 0.95], "index", 0, label=1)
    _press(buffer, 0.004, [0.1, 0.9], "ring", 5, at_edge=True)
    assert buffer.num_fused == 1 and buffer.point_labels_used()[1].tolist() == [1, 1]
    expected = 0.95 * 0.9 / (0.95 * 0.9 + 0.05 * 0.1)
    assert buffer.tensors()["labelled_weights"][-1].item() == pytest.approx(expected, rel=1e-5)
    assert buffer.num_labelled == 2
