"""Keyframe window (recent + by loss), eviction, the touch replay buffer and the label vote."""

from __future__ import annotations

import pytest
import torch

from neuralfeels_sem.mapping import label_vote
from neuralfeels_sem.mapping.keyframes import KeyframeBuffer
from neuralfeels_sem.mapping.label_vote import (
    LabelVote,
    outvoted_touches,
    press_events,
    steady_presses,
)
from neuralfeels_sem.mapping.mapper import MapperConfig
from neuralfeels_sem.mapping.touch_memory import TouchBuffer

CPU = torch.device("cpu")


def vote(**settings) -> LabelVote:
    """The vote's rules one at a time: `settings` (radius=..., ...) over a vote with support,
    presses, steady presses and the separate support radius off; the command line's values
    otherwise."""
    base = {"min_support": 0, "press_gap": 0, "support_radius": None, "steady_frames": 0,
            "press_reach": None}  # fmt: skip
    base.update(settings)
    return LabelVote.from_config(MapperConfig(**{f"label_vote_{k}": v for k, v in base.items()}))


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
    touches = TouchBuffer(CPU)
    touches.add(torch.zeros(4, 3), torch.tensor([0.0, 0.0, 1.0]), label=1, weight=0.8)
    touches.add(torch.ones(4, 3), torch.tensor([1.0, 0.0, 0.0]), label=-1, weight=0.0)
    cat = touches.tensors()
    assert cat["points"].shape == (8, 3) and cat["labelled_points"].shape == (4, 3)
    assert torch.equal(cat["labelled_labels"], torch.ones(4, dtype=torch.long))
    assert torch.allclose(cat["labelled_weights"], torch.full((4,), 0.8))
    assert torch.equal(cat["axes"][5], torch.tensor([1.0, 0.0, 0.0]))
    assert (touches.num_touches, touches.num_labelled) == (2, 1)
    copy = TouchBuffer(CPU)
    copy.load_state_dict(touches.state_dict())
    for key, value in copy.tensors().items():
        assert torch.equal(value, cat[key]), key


def test_label_vote_drops_a_touch_its_neighbours_contradict() -> None:
    axis = torch.tensor([0.0, 0.0, 1.0])
    touches = TouchBuffer(CPU, vote(radius=0.01, min_neighbours=3))
    centre = torch.tensor([0.02, 0.0, 0.0])
    for k in range(5):  # five fabric touches around one point
        offset = torch.tensor([0.002 * k, 0.001, 0.0])
        touches.add(centre + offset + torch.zeros(4, 3), axis, label=2, weight=0.9)
    touches.add(centre + torch.zeros(4, 3), axis, label=0, weight=0.95)  # one wrong plastic
    far = torch.tensor([-0.05, 0.0, 0.0])
    touches.add(far + torch.zeros(4, 3), axis, label=0, weight=0.9)  # plastic elsewhere
    touches.add(torch.ones(4, 3), axis, label=-1, weight=0.0)  # unlabelled: never votes
    assert touches.num_outvoted == 1  # current without asking for the tensors first
    cat = touches.tensors()
    assert touches.num_outvoted == 1
    assert cat["labelled_points"].shape == (6 * 4, 3)
    assert (cat["labelled_labels"] == 0).sum() == 4  # only the far plastic touch is left
    # Without a vote every labelled touch is used.
    plain = TouchBuffer(CPU)
    plain.load_state_dict(touches.state_dict())
    assert plain.tensors()["labelled_points"].shape == (7 * 4, 3) and plain.num_outvoted == 0
    # A touch with too few neighbours, or enough agreeing ones, is kept.
    c = torch.tensor([[0.0, 0, 0], [0.001, 0, 0], [0.0, 0.001, 0], [0.001, 0.001, 0]])
    assert not outvoted_touches(c[:3], torch.tensor([0, 2, 2]), 0.01, 3, 0.25).any()
    assert not outvoted_touches(c, torch.tensor([0, 0, 2, 2]), 0.01, 3, 0.25).any()
    assert outvoted_touches(c, torch.tensor([0, 2, 2, 2]), 0.01, 3, 0.25).tolist() == [
        True,
        False,
        False,
        False,
    ]
    with pytest.raises(ValueError, match="centroids"):
        outvoted_touches(c[:, :2], torch.tensor([0, 0, 2, 2]), 0.01, 3, 0.25)


def test_label_vote_min_support_drops_a_lone_touch_until_another_agrees() -> None:
    c = torch.tensor([[0.0, 0, 0], [0.001, 0, 0], [0.05, 0, 0]])
    labels = torch.tensor([2, 2, 0])  # two agreeing fabric touches, one lone plastic far off
    assert outvoted_touches(c, labels, 0.01, 3, 0.25).tolist() == [False, False, False]
    assert outvoted_touches(c, labels, 0.01, 3, 0.25, min_support=1).tolist() == [
        False,
        False,
        True,
    ]
    # a second plastic touch next to the first backs it
    c2 = torch.cat([c, torch.tensor([[0.051, 0, 0]])])
    labels2 = torch.tensor([2, 2, 0, 0])
    assert not outvoted_touches(c2, labels2, 0.01, 3, 0.25, min_support=1).any()

    axis = torch.tensor([0.0, 0.0, 1.0])
    touches = TouchBuffer(CPU, vote(radius=0.01, min_support=1))
    touches.add(torch.zeros(4, 3), axis, label=1, weight=0.9)
    assert touches.num_outvoted == 1 and touches.tensors()["labelled_points"].shape == (0, 3)
    touches.add(torch.full((4, 3), 0.001), axis, label=1, weight=0.9)
    assert touches.num_outvoted == 0 and touches.tensors()["labelled_points"].shape == (8, 3)


def test_press_events_group_a_fingers_consecutive_frames() -> None:
    fingers = ["index", "index", "ring", "index", "index", None, None]
    frames = [1, 2, 2, 6, 7, 7, 7]
    assert press_events(fingers, frames, gap=2).tolist() == [0, 0, 2, 3, 3, 5, 6]
    assert press_events(fingers, frames, gap=0).tolist() == list(range(7))
    with pytest.raises(ValueError, match="fingers"):
        press_events(fingers, frames[:-1], gap=2)


def test_a_press_ends_where_its_finger_has_slid_past_the_reach() -> None:
    """The index finger slides 4 mm a frame: with a 1 cm reach its press ends at the third
    frame past the start (1.2 cm away), and the new press measures from there; the ring
    finger's touches are their own press either way."""
    fingers = ["index"] * 6 + ["ring"]
    frames = [0, 1, 2, 3, 4, 5, 1]
    centroids = torch.tensor([[0.004 * i, 0.0, 0.0] for i in range(6)] + [[0.0, 0.05, 0.0]])
    assert press_events(fingers, frames, 2).tolist() == [0, 0, 0, 0, 0, 0, 6]
    split = press_events(fingers, frames, 2, centroids, reach=0.01)
    assert split.tolist() == [0, 0, 0, 3, 3, 3, 6]
    with pytest.raises(ValueError, match="one centroid per touch"):
        press_events(fingers, frames, 2, centroids[:3], reach=0.01)
    with pytest.raises(ValueError, match="label_vote_press_reach=0.0 must be > 0"):
        MapperConfig(num_classes=2, label_vote_press_reach=0.0)


def test_a_reading_across_a_border_is_steady_in_its_own_press() -> None:
    """A finger reads fabric for 6 frames as it slides, then plastic for 3 frames 2 cm on:
    one press by time alone (plastic 3 of 9 frames, not steady, so the lone plastic part is
    left out), two with a 1 cm reach (plastic steady in its own)."""
    axis = torch.tensor([0.0, 0.0, 1.0])
    for reach, plastic_kept in ((None, False), (0.01, True)):
        touches = TouchBuffer(
            CPU, vote(radius=0.01, min_support=1, steady_frames=3, press_gap=2, press_reach=reach)
        )
        for frame in range(9):
            x = 0.002 * frame if frame < 6 else 0.03 + 0.001 * frame
            touches.add(torch.full((4, 3), x), axis, label=2 if frame < 6 else 0, weight=1.0,
                        finger="index", frame_index=frame)  # fmt: skip
        used = torch.cat(touches.point_labels_used())
        assert bool((used == 0).any()) is plastic_kept, reach
        assert int((used == 2).sum()) == 24  # the fabric frames back themselves either way


def test_frames_of_one_press_do_not_back_each_other() -> None:
    # Three fabric presses and, in the same place, one press misread as plastic in 3 frames.
    c = torch.tensor([[0.0, 0, 0], [0.002, 0, 0], [0, 0.002, 0]] + [[0.001, 0.001, 0]] * 3)
    labels = torch.tensor([2, 2, 2, 0, 0, 0])
    per_frame = outvoted_touches(c, labels, 0.01, 3, 0.25, min_support=1)
    assert not per_frame.any()  # 2 of 5 neighbours agree with each plastic frame
    events = torch.tensor([0, 1, 2, 3, 3, 3])
    per_press = outvoted_touches(c, labels, 0.01, 3, 0.25, min_support=1, events=events)
    assert per_press.tolist() == [False, False, False, True, True, True]
    # A lone press seen in two frames has no support from another press.
    lone = torch.tensor([[0.0, 0, 0], [0.001, 0, 0]])
    same = torch.tensor([7, 7])
    assert not outvoted_touches(lone, torch.tensor([1, 1]), 0.01, 3, 0.25, 1).any()
    assert outvoted_touches(lone, torch.tensor([1, 1]), 0.01, 3, 0.25, 1, events=same).all()
    with pytest.raises(ValueError, match="events"):
        outvoted_touches(lone, torch.tensor([1, 1]), 0.01, 3, 0.25, 1, events=same[:1])


def test_touch_buffer_counts_presses_and_keeps_them_in_its_state() -> None:
    axis = torch.tensor([0.0, 0.0, 1.0])
    touches = TouchBuffer(CPU, vote(radius=0.01, min_support=1, press_gap=2))
    touches.add(torch.zeros(4, 3), axis, label=1, weight=0.9, finger="ring", frame_index=5)
    touches.add(torch.full((4, 3), 0.001), axis, label=1, weight=0.9, finger="ring", frame_index=6)
    assert touches.num_outvoted == 2  # one press, nobody else backs it
    touches.add(torch.full((4, 3), 0.002), axis, label=1, weight=0.9, finger="thumb", frame_index=6)
    assert touches.num_outvoted == 0  # another finger agrees
    state = touches.state_dict()
    assert state["fingers"] == ["ring", "ring", "thumb"] and state["frames"] == [5, 6, 6]
    restored = TouchBuffer(CPU, vote(radius=0.01, min_support=1, press_gap=2))
    restored.load_state_dict(state)
    assert restored.num_outvoted == 0
    # A checkpoint written before presses were recorded: every touch votes on its own.
    old = {k: v for k, v in state.items() if k not in ("fingers", "frames")}
    restored.load_state_dict(old)
    assert restored.num_outvoted == 0 and restored.tensors()["labelled_points"].shape == (12, 3)


def test_support_is_looked_for_within_its_own_radius() -> None:
    # Two fabric presses 3 cm apart: neither backs the other within the 2 cm vote radius.
    c = torch.tensor([[0.0, 0, 0], [0.03, 0, 0], [0.2, 0, 0]])
    labels = torch.tensor([2, 2, 0])
    events = torch.tensor([0, 1, 2])
    alone = outvoted_touches(c, labels, 0.02, 3, 0.25, 1, events)
    assert alone.tolist() == [True, True, True]
    wide = outvoted_touches(c, labels, 0.02, 3, 0.25, 1, events, support_radius=0.04)
    assert wide.tolist() == [False, False, True]  # the far plastic press has no backing
    # The contradiction rule keeps its own radius.
    crowd = torch.tensor([[0.0, 0, 0], [0.001, 0, 0], [0.0, 0.001, 0], [0.001, 0.001, 0]])
    wrong_in_crowd = outvoted_touches(
        crowd, torch.tensor([0, 2, 2, 2]), 0.01, 3, 0.25, 1, support_radius=0.05
    )
    assert wrong_in_crowd.tolist() == [True, False, False, False]


def test_a_steady_press_backs_itself_where_nobody_else_touched() -> None:
    # One finger presses a small insert nobody else reaches: 4 frames read plastic (0),
    # far from the fabric (2) presses elsewhere.
    fingers, frames = ["ring"] * 4 + ["index", "thumb"], [3, 4, 5, 6, 4, 4]
    c = torch.tensor([[0.1, 0, 0]] * 4 + [[0.0, 0, 0], [0.001, 0, 0]])
    labels = torch.tensor([0, 0, 0, 0, 2, 2])
    lone = vote(radius=0.01, min_support=1, press_gap=2)
    assert lone.outvoted(c, labels, fingers, frames).tolist() == [True] * 4 + [False] * 2
    steady = vote(radius=0.01, min_support=1, press_gap=2, steady_frames=3)
    assert not steady.outvoted(c, labels, fingers, frames).any()
    # Two frames are not steady; nor is a label read in only a minority of the press's frames.
    brief = steady.outvoted(c[2:], labels[2:], fingers[2:], frames[2:])
    assert brief.tolist() == [True, True, False, False]
    mixed = torch.tensor([0, 1, 1, 1, 2, 2])
    assert steady.outvoted(c, mixed, fingers, frames).tolist() == [True] + [False] * 5


def test_steady_presses_count_frames_per_label_of_each_press() -> None:
    events = torch.tensor([0, 0, 0, 0, 1, 1, 1])
    labels = torch.tensor([1, 1, 1, 2, 3, 3, 3])
    frames_per_press = torch.bincount(events)
    got = steady_presses(events, labels, frames_per_press, 3)
    assert got.tolist() == [True, True, True, False, True, True, True]
    # Patch readings: a press across a border reads two materials in every frame (two items
    # per frame of the same press); each is steady on its own.
    items = torch.tensor([0, 0, 0, 0, 0, 0])
    both = steady_presses(items, torch.tensor([1, 2, 1, 2, 1, 2]), torch.tensor([3]), 3)
    assert both.all()
    assert steady_presses(events, labels, frames_per_press, 0) is None
    assert steady_presses(events[:0], labels[:0], frames_per_press, 3) is None


def test_a_steady_press_among_disagreeing_neighbours_is_still_outvoted() -> None:
    crowd = [[0.0, 0, 0], [0.001, 0, 0], [0.0, 0.001, 0]]
    c = torch.tensor(crowd + [[0.001, 0.001, 0]] * 3)
    labels = torch.tensor([2, 2, 2, 0, 0, 0])
    fingers, frames = ["index", "middle", "thumb"] + ["ring"] * 3, [1, 1, 1, 2, 3, 4]
    steady = vote(radius=0.01, min_neighbours=3, min_support=1, press_gap=2, steady_frames=3)
    assert steady.outvoted(c, labels, fingers, frames).tolist() == [False] * 3 + [True] * 3


def test_steady_frames_must_not_be_negative() -> None:
    with pytest.raises(ValueError, match="label_vote_steady_frames"):
        MapperConfig(label_vote_steady_frames=-1)


def test_presses_count_mapped_frames_when_realtime_pacing_skips_some() -> None:
    # One ring press mapped at every third frame (realtime pacing): one press, which no
    # other press backs; with every frame index counted it would be three that back each other.
    axis = torch.tensor([0.0, 0.0, 1.0])
    touches = TouchBuffer(CPU, vote(radius=0.01, min_support=1, press_gap=2))
    for step, frame in enumerate((10, 13, 16)):
        touches.note_frame(frame)
        touches.add(torch.full((4, 3), 0.001 * step), axis, 1, 0.9, "ring", frame)
    assert touches.num_outvoted == 3
    # A finger that lifts for two mapped frames starts a new press, which backs the first.
    for frame in (19, 22):
        touches.note_frame(frame)
    touches.note_frame(25)
    touches.add(torch.full((4, 3), 0.004), axis, 1, 0.9, "ring", 25)
    assert touches.num_outvoted == 0
    # The mapped frames travel with the state; an older state falls back to the touches'.
    state = touches.state_dict()
    assert state["mapped_frames"] == [10, 13, 16, 19, 22, 25]
    restored = TouchBuffer(CPU, vote(radius=0.01, min_support=1, press_gap=2))
    restored.load_state_dict(state)
    assert restored.num_outvoted == 0
    older = {k: v for k, v in state.items() if k != "mapped_frames"}
    restored.load_state_dict(older)
    assert restored.num_outvoted == 4  # frames 16 and 25 are ranks 2 and 3: one press


def dense_outvoted(centroids, labels, radius, min_neighbours, min_agreement, min_support,
                   events, support_radius, steady) -> torch.Tensor:  # fmt: skip
    """The vote as (T, T) membership products over every pair: the reference the
    neighbourhood count must equal."""
    distances = torch.cdist(centroids.double(), centroids.double())
    members = torch.nn.functional.one_hot(torch.unique(events, return_inverse=True)[1]).double()
    other = events[None, :] != events[:, None]
    same = labels[None, :] == labels[:, None]

    def presses(mask: torch.Tensor) -> torch.Tensor:
        return ((mask.double() @ members) > 0).sum(1)

    neighbours, agree = (
        presses(other & (distances < radius)),
        presses(other & same & (distances < radius)),
    )
    outvoted = (neighbours >= min_neighbours) & (agree < min_agreement * neighbours.float())
    if min_support > 0:
        support = radius if support_radius is None else support_radius
        unsupported = presses(other & same & (distances < support)) < min_support
        outvoted |= unsupported if steady is None else unsupported & ~steady
    return outvoted


@pytest.mark.parametrize("table_cells", [label_vote.TABLE_CELLS, 0])
@pytest.mark.parametrize(
    "min_support, support_radius", [(0, None), (1, None), (1, 0.04), (2, 0.04)]
)
def test_the_vote_over_neighbourhoods_equals_the_dense_count(
    min_support, support_radius, table_cells, monkeypatch
) -> None:
    """Counting other presses only among the pairs within the radii (KD-tree) outvotes the
    same touches as counting them over every pair, for clustered presses with several
    frames each, with and without steady presses, at two radii and two agreement shares;
    presses counted in the boolean table and by sorting (a table over its size)."""
    monkeypatch.setattr(label_vote, "TABLE_CELLS", table_cells)
    gen = torch.Generator().manual_seed(3)
    centres = torch.rand(120, 3, generator=gen) * 0.06
    events = torch.sort(torch.randint(0, 120, (400,), generator=gen)).values
    centroids = centres[events] + 0.003 * torch.randn(400, 3, generator=gen)
    labels = torch.randint(0, 3, (400,), generator=gen)
    steady = torch.rand(400, generator=gen) < 0.5
    outvoted_any = 0
    for radius, agreement, steady_or_none in ((0.005, 0.25, None), (0.02, 1 / 3, steady)):
        args = (centroids, labels, radius, 3, agreement, min_support, events, support_radius)
        got = outvoted_touches(*args, steady_or_none)
        assert torch.equal(got, dense_outvoted(*args, steady_or_none)), radius
        outvoted_any += int(got.sum())
    assert 0 < outvoted_any < 800  # the vote leaves some out, not all


def test_touch_tensors_joined_as_touches_come_equal_joining_them_all() -> None:
    """New touches append to the joined tensors; a relabelled or moved touch re-joins from
    itself on: at every point the tensors equal the per-touch lists concatenated whole."""
    gen = torch.Generator().manual_seed(5)
    buf = TouchBuffer(CPU)

    def check() -> None:
        got = buf.tensors()
        for key, items in (("points", buf._points), ("axes", buf._axes),
                           ("labels", buf._labels), ("weights", buf._weights)):  # fmt: skip
            assert torch.equal(got[key], torch.cat(items)), key

    for frame in range(6):
        label = -1 if frame in (1, 4) else frame % 3
        buf.add(torch.rand(8, 3, generator=gen), torch.tensor([0.0, 0.0, 1.0]), label, 1.0,
                finger="index", frame_index=frame)  # fmt: skip
        check()
    buf._relabel(1, 2, 0.5)  # what press fusion does to an abstained touch
    check()
    assert buf.tensors()["labels"][8:16].tolist() == [2] * 8
    buf.move_frame(4, torch.eye(3), torch.tensor([0.01, 0.0, 0.0]))
    check()
    buf.add(torch.rand(8, 3, generator=gen), torch.tensor([0.0, 0.0, 1.0]), 0, 1.0,
            finger="index", frame_index=6)  # fmt: skip
    check()
    restored = TouchBuffer(CPU)
    restored.load_state_dict(buf.state_dict())
    assert torch.equal(restored.tensors()["points"], buf.tensors()["points"])
