"""The touch score, the planner's ranking and regrasp decisions, and the trajectory's regrasp."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.sim.touch_advice import TouchAdvice, TouchScoreConfig
from neuralfeels_sem.sim.touch_planner import TouchPlanner, TouchPlannerConfig
from neuralfeels_sem.sim.trajectory import ObjectTrajectory

SCORE = TouchScoreConfig(uncertainty_weight=1.0, novelty_weight=1.0, novelty_m=0.02, unseen_m=0.01)


def _advice(touched=((0.0, 0.0, 0.04),)) -> TouchAdvice:
    surface = np.array([[0.0, 0.0, 0.04], [0.04, 0.0, 0.0], [0.0, 0.04, 0.0]])
    return TouchAdvice(surface, np.array([0.0, 0.5, 1.0]), np.array(touched), SCORE, 7)


def test_score_mixes_entropy_at_the_nearest_sample_and_distance_to_touches() -> None:
    advice = _advice()
    points = np.array([[0.0, 0.0, 0.041], [0.04, 0.0, 0.0], [0.0, 0.04, 0.005], [0.1, 0.1, 0.1]])
    np.testing.assert_allclose(advice.uncertainty(points), [0.0, 0.5, 1.0, 1.0])
    # novelty: 1 mm from the touch -> 0.05; the others farther than novelty_m -> 1
    np.testing.assert_allclose(advice.score(points), [0.025, 0.75, 1.0, 1.0], atol=1e-9)
    # before any touch every point is fully novel
    assert (_advice(touched=np.zeros((0, 3))).score(points) >= 0.5).all()


def test_the_border_term_marks_the_band_between_two_labels_touches() -> None:
    touched = np.array([[0.0, 0.0, 0.0], [0.04, 0.0, 0.0], [0.05, 0.0, 0.0]])
    labels = np.array([0, 1, 1])
    surface = np.array([[0.02, 0.0, 0.0], [0.0, 0.0, 0.001], [0.06, 0.0, 0.0]])
    config = TouchScoreConfig(novelty_weight=0.0, boundary_m=0.02)
    advice = TouchAdvice(surface, np.full(3, 0.1), touched, config, 0, labels=labels)
    points = np.array([[0.02, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.001], [0.06, 0.0, 0.0]])
    # halfway: 1; 1 cm from label 0 and 3 cm from label 1: 1 - 2/2 = 0; beside a touch: 0
    np.testing.assert_allclose(advice.border(points), [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(advice.border([[0.015, 0.0, 0.0]]), [0.5], atol=1e-12)
    # the uncertainty is the larger of the entropy and the border term
    np.testing.assert_allclose(advice.uncertainty(points[[0, 2]]), [1.0, 0.1], atol=1e-12)
    # one label read, no labels given, or the term off: the entropy alone
    one = TouchAdvice(surface, np.full(3, 0.1), touched, config, 0, labels=np.ones(3, int))
    unlabelled = TouchAdvice(surface, np.full(3, 0.1), touched, config, 0)
    off = TouchAdvice(surface, np.full(3, 0.1), touched, TouchScoreConfig(), 0, labels=labels)
    for advice in (one, unlabelled, off):
        np.testing.assert_allclose(advice.uncertainty(surface[:1]), [0.1])
    with pytest.raises(ValueError, match="3 touches but 2 labels"):
        TouchAdvice(surface, np.zeros(3), touched, config, 0, labels=np.zeros(2, int))
    with pytest.raises(ValueError, match="boundary_m"):
        TouchScoreConfig(boundary_m=0.0)


def test_suggestions_are_best_first_and_spread_and_the_hotspot_is_the_best() -> None:
    advice = _advice()
    points, scores = advice.suggestions(2)
    np.testing.assert_allclose(points, [[0.0, 0.04, 0.0], [0.04, 0.0, 0.0]])
    assert list(scores) == sorted(scores, reverse=True)
    np.testing.assert_allclose(advice.hotspot(), [0.0, 0.04, 0.0])


def test_planner_ranks_candidates_best_first_and_keeps_ties_in_order() -> None:
    planner = TouchPlanner()
    points = np.array([[0.0, 0.0, 0.04], [0.0, 0.04, 0.0], [0.04, 0.0, 0.0], [0.0, 0.04, 0.0]])
    order, _ = planner.rank(points)
    np.testing.assert_array_equal(order, [0, 1, 2, 3])  # no advice yet: the sampler's order
    planner.advice = _advice()
    order, scores = planner.rank(points)
    np.testing.assert_array_equal(order, [1, 3, 2, 0])
    assert scores[order[0]] == pytest.approx(1.0)


def test_an_edge_contact_ranks_below_a_full_one_of_a_slightly_lower_score() -> None:
    # Scores 1.0 (edge contact: 3 of 10 rays) and 0.75 (full contact): the full one first,
    # unless the ranking is told to ignore contact; the returned scores are the advice's.
    points = np.array([[0.0, 0.04, 0.0], [0.04, 0.0, 0.0]])
    planner = TouchPlanner()
    planner.advice = _advice()
    order, scores = planner.rank(points, np.array([0.3, 1.0]))
    np.testing.assert_array_equal(order, [1, 0])
    np.testing.assert_allclose(scores, [1.0, 0.75])
    plain = TouchPlanner(TouchPlannerConfig(weigh_by_contact=False))
    plain.advice = _advice()
    np.testing.assert_array_equal(plain.rank(points, np.array([0.3, 1.0]))[0], [0, 1])
    with pytest.raises(ValueError, match="contact"):
        planner.rank(points, np.array([0.3, 1.5]))


def test_a_regrasp_is_due_after_enough_starved_contacts_and_not_too_often() -> None:
    planner = TouchPlanner(
        TouchPlannerConfig(regrasp_below=0.5, regrasp_after=3, regrasp_gap_s=5.0)
    )
    assert not planner.note_choice(0.0, 0.1)  # no advice: never starved
    planner.advice = _advice()
    assert [planner.note_choice(t, 0.1) for t in (1.0, 1.1, 1.2)] == [False, False, True]
    assert not any(planner.note_choice(t, 0.1) for t in (1.3, 1.4, 1.5))  # within the gap
    assert not planner.note_choice(7.0, 0.9)  # a good touch resets the count
    assert [planner.note_choice(t, 0.1) for t in (7.1, 7.2, 7.3)] == [False, False, True]


def test_a_regrasp_is_due_when_the_hotspot_is_out_of_the_turns_reach() -> None:
    planner = TouchPlanner(TouchPlannerConfig(out_of_reach_m=0.03, regrasp_gap_s=2.0))
    assert not planner.note_choice(0.0, 0.9, 0.08)  # no advice yet
    planner.advice = _advice()
    assert not planner.note_choice(1.0, 0.9, 0.02)  # within reach, good scores
    assert planner.note_choice(1.1, 0.9, 0.04)  # beyond reach: regrasp at once
    assert not planner.note_choice(2.0, 0.9, 0.04)  # but not within the gap
    assert planner.note_choice(3.2, 0.9, 0.04)
    off = TouchPlanner(TouchPlannerConfig(out_of_reach_m=None))
    off.advice = _advice()
    assert not off.note_choice(1.0, 0.9, 0.08)
    with pytest.raises(ValueError, match="out_of_reach_m"):
        TouchPlannerConfig(out_of_reach_m=0.0)


def test_regrasp_move_slides_the_hotspot_to_the_fingers_along_the_palm() -> None:
    planner = TouchPlanner(TouchPlannerConfig(max_offset_m=0.05, keep_m=0.02))
    far = np.array([0.09, 0.01, 0.0])  # the far end of a long object, along x
    planner.advice = TouchAdvice(far[None], np.ones(1), np.zeros((0, 3)), SCORE, 3)
    up = np.array([0.0, 0.0, 1.0])
    axis, offset = planner.regrasp_move(np.eye(4), up)
    np.testing.assert_allclose(axis, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(offset, [-0.05, 0.0, 0.0])  # 7 cm wanted, 5 cm allowed
    # a hotspot straight above the palm: never an axis (or a slide) along the palm normal
    planner.advice = TouchAdvice(
        np.array([[0.0, 0.0, 0.06]]), np.ones(1), np.zeros((0, 3)), SCORE, 3
    )
    axis, offset = planner.regrasp_move(np.eye(4), up)
    assert abs(axis @ up) < 0.9 and abs(offset @ up) < 1e-12
    assert TouchPlanner().regrasp_move(np.eye(4), up) is None  # no advice, no move


def _unconfirmed_advice() -> TouchAdvice:
    """Two readings to confirm: one where the map is sure (entropy 0), one where it is not."""
    surface = np.array([[0.0, 0.0, 0.04], [0.04, 0.0, 0.0], [0.0, 0.04, 0.0]])
    unconfirmed = np.array([[0.0, 0.0, 0.041], [0.0, 0.041, 0.0]])
    return TouchAdvice(surface, np.array([0.0, 0.5, 1.0]), surface[:1], SCORE, 7, unconfirmed)


def test_a_confirm_regrasp_is_due_when_no_touch_could_reach_an_unconfirmed_reading() -> None:
    planner = TouchPlanner(TouchPlannerConfig(confirm_regrasp_after=2, regrasp_gap_s=1.0))
    planner.advice = _unconfirmed_advice()
    near, far = np.array([[0.0, 0.04, 0.0]]), np.array([[0.04, 0.0, 0.0]])
    assert planner.confirm_reachable(near) is True and planner.confirm_reachable(far) is False
    hits = [planner.note_choice(t, 0.9, None, r) for t, r in ((1, False), (2, True), (3, False))]
    assert hits == [False, False, False]  # a reachable one resets the count
    assert planner.note_choice(4.0, 0.9, None, False) and planner.due_reason == "confirm"
    np.testing.assert_allclose(planner.aim, [0.0, 0.041, 0.0])  # the less certain of the two
    axis, offset = planner.regrasp_move(np.eye(4), np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0])  # turns about the aim's direction
    np.testing.assert_allclose(offset, [0.0, -0.021, 0.0])  # to within keep_m (2 cm)
    assert planner.aim is None  # the next regrasp goes back to the hotspot
    # nothing to confirm (None) never counts; off by default
    assert not any(planner.note_choice(t, 0.9, None, None) for t in (10.0, 11.0, 12.0))
    off = TouchPlanner()
    off.advice = _unconfirmed_advice()
    assert not any(off.note_choice(t, 0.9, None, False) for t in range(1, 20))
    empty = TouchPlanner()
    empty.advice = _advice()
    assert empty.confirm_reachable(near) is None


def test_a_starved_regrasp_keeps_aiming_at_the_hotspot() -> None:
    planner = TouchPlanner(TouchPlannerConfig(regrasp_after=1, confirm_regrasp_after=5))
    planner.advice = _unconfirmed_advice()
    assert planner.note_choice(1.0, 0.1, None, False) and planner.due_reason == "starved"
    assert planner.aim is None


@pytest.mark.parametrize(
    "key, value",
    [
        ("candidates", 0),
        ("regrasp_below", 1.5),
        ("regrasp_after", 0),
        ("confirm_regrasp_after", 0),
        ("axes", [[0, 0, 0]]),
    ],
)
def test_bad_planner_settings_are_value_errors_naming_the_key(key, value) -> None:
    with pytest.raises(ValueError, match=f"sensor.planner.{key}"):
        TouchPlannerConfig(**{key: value})


def test_bad_score_weights_are_value_errors() -> None:
    with pytest.raises(ValueError, match="mapping.advisor.score"):
        TouchScoreConfig(uncertainty_weight=0.0, novelty_weight=0.0)


def test_trajectory_regrasp_turns_about_the_new_axis_after_a_smooth_slide() -> None:
    centre = np.array([0.0, 0.0, 0.2])
    traj = ObjectTrajectory(centre, (0, 0, 1), 30.0, wobble_deg=0.0, sway_m=0.0, slide_s=1.0)
    before = traj.pose(2.0)
    k, start = traj.regrasp(1.0, (1.0, 0.0, 0.0), (0.03, 0.0, 0.0))
    assert start == 2.0 and k == 1  # never earlier than a pose already given out
    np.testing.assert_allclose(traj.pose(2.0), before, atol=1e-12)
    np.testing.assert_allclose(traj.pose(2.5)[:3, 3], centre + [0.015, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(traj.pose(3.0)[:3, 3], centre + [0.03, 0.0, 0.0], atol=1e-12)
    step = traj.pose(3.5)[:3, :3] @ traj.pose(3.0)[:3, :3].T  # about x now
    np.testing.assert_allclose(step @ [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(traj.segment_centre(1), centre + [0.03, 0.0, 0.0])
    assert traj.settled(1) == 3.0 and traj.regrasps[0][0] == 2.0


def test_alternation_goes_on_after_a_regrasp() -> None:
    z, y, x = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]
    traj = ObjectTrajectory(np.zeros(3), z, alternate_axis=y, alternate_every_s=2.0, wobble_deg=0.0)
    traj.pose(3.0)
    traj.regrasp(3.0, x, np.zeros(3))
    axes = [traj.segment_axis(traj.segment(t)) for t in (1.0, 2.5, 3.5, 5.5, 7.5)]
    np.testing.assert_allclose(axes, [z, y, x, y, x])


def test_advice_normals_must_match_the_surface_samples() -> None:
    surface = np.zeros((3, 3))
    with pytest.raises(ValueError, match="3 surface samples but 2 normals"):
        TouchAdvice(surface, np.zeros(3), np.zeros((0, 3)), SCORE, 0, normals=np.ones((2, 3)))
    assert _advice().normals is None  # unknown: a chosen turn ignores facing
