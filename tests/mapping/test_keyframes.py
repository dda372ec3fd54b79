"""Keyframe window (recent + by loss), eviction and the touch replay buffer."""

from __future__ import annotations

import torch

from neuralfeels_sem.mapping.keyframes import KeyframeBuffer, TouchBuffer


def filled(n: int, **kwargs) -> KeyframeBuffer:
    buf = KeyframeBuffer(**kwargs)
    for i in range(n):
        buf.add(torch.full((10, 3), float(i)), torch.zeros(3), frame_index=i)
    return buf


def test_window_is_recent_frames_plus_high_loss_frames() -> None:
    buf = filled(10, max_keyframes=50, window_recent=3, window_by_loss=2)
    buf.update_losses(list(range(10)), [1e-9] * 10)
    buf.update_losses([2, 5], [1.0, 1.0])
    window = buf.window(torch.Generator().manual_seed(0))
    assert window == [2, 5, 7, 8, 9]


def test_short_buffer_window_is_everything() -> None:
    buf = filled(2, max_keyframes=50, window_recent=3, window_by_loss=2)
    assert buf.window(torch.Generator()) == [0, 1]


def test_eviction_drops_lowest_loss_outside_recent_window() -> None:
    buf = filled(5, max_keyframes=5, window_recent=2, window_by_loss=1)
    buf.update_losses([0, 1, 2, 3, 4], [0.5, 0.1, 0.9, 0.3, 0.0])
    buf.add(torch.ones(4, 3), torch.zeros(3), frame_index=5)
    assert buf.frame_indices == [0, 2, 3, 4, 5]
    assert len(buf) == 5


def test_empty_keyframe_is_not_stored() -> None:
    buf = filled(0, max_keyframes=5, window_recent=2, window_by_loss=1)
    buf.add(torch.zeros(0, 3), torch.zeros(3), frame_index=0)
    assert len(buf) == 0


def test_touch_buffer_keeps_labelled_subset_and_round_trips() -> None:
    touches = TouchBuffer(torch.device("cpu"))
    touches.add(torch.zeros(4, 3), torch.tensor([0.0, 0.0, 1.0]), label=1, weight=0.8)
    touches.add(torch.ones(4, 3), torch.tensor([1.0, 0.0, 0.0]), label=-1, weight=0.0)
    cat = touches.tensors()
    assert cat["points"].shape == (8, 3) and cat["labelled_points"].shape == (4, 3)
    assert torch.equal(cat["labelled_labels"], torch.ones(4, dtype=torch.long))
    assert torch.allclose(cat["labelled_weights"], torch.full((4,), 0.8))
    assert torch.equal(cat["axes"][5], torch.tensor([1.0, 0.0, 0.0]))
    assert (touches.num_touches, touches.num_labelled) == (2, 1)
    copy = TouchBuffer(torch.device("cpu"))
    copy.load_state_dict(touches.state_dict())
    for key, value in copy.tensors().items():
        assert torch.equal(value, cat[key]), key
