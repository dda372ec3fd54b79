"""sensor.planner.turn=advice and advance: the sweep gain, the choice between the plan and
a turn, the trajectory's previews and turns, and the planner's bookkeeping."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.geometry import rotation_matrix
from neuralfeels_sem.sim.touch_advice import TouchAdvice, TouchScoreConfig
from neuralfeels_sem.sim.touch_planner import TouchPlanner, TouchPlannerConfig
from neuralfeels_sem.sim.trajectory import ObjectTrajectory
from neuralfeels_sem.sim.turn_choice import Reach, TurnChooser, sweep_gain

SPEED = np.deg2rad(30.0)
AXES = np.eye(3)


def _sphere(n: int = 400, radius: float = 0.04) -> np.ndarray:
    """Fibonacci points on a sphere about the origin."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5**0.5) * i
    r = np.sqrt(1.0 - z * z)
    return radius * np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _poses(axis: np.ndarray, ahead: np.ndarray) -> np.ndarray:
    out = np.tile(np.eye(4), (len(ahead), 1, 1))
    for pose, tau in zip(out, ahead):
        pose[:3, :3] = rotation_matrix(axis, SPEED * tau)
    return out


def _chooser(gain: float = 1.25) -> TurnChooser:
    chooser = TurnChooser(check_s=1.0, horizon_s=3.0, gain=gain, reach_m=0.01, axes=AXES)
    chooser.note_reach(np.array([[0.04, 0.0, 0.0], [0.04, 0.005, 0.0]]))  # a finger at +x
    return chooser


def test_the_gain_counts_each_sample_brought_to_the_fingers_once() -> None:
    surface = np.array([[0.04, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.04]])
    scores = np.array([0.5, 0.25, 1.0])
    reach = Reach(np.array([[0.04, 0.0, 0.0]]))
    still = np.tile(np.eye(4), (3, 1, 1))
    assert sweep_gain(surface, scores, still, reach, 0.01) == 0.5  # three poses, counted once
    quarter = _poses(AXES[2], np.array([3.0]))  # +90 degrees about z: +y to -x, +x to +y
    spun = np.concatenate([still[:1], _poses(AXES[2], np.array([-3.0]))])  # then +y to +x
    assert sweep_gain(surface, scores, quarter, reach, 0.01) == 0.0
    assert sweep_gain(surface, scores, spun, reach, 0.01) == 0.75


def test_with_a_facing_bound_a_sample_counts_only_where_it_faces_as_the_surface_met() -> None:
    surface = np.array([[0.04, 0.0, 0.0], [0.0, 0.04, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])  # an edge facing up; a flank
    scores = np.array([1.0, 0.5])
    met = np.array([[1.0, 0.0, 0.0]])  # the finger at +x met a surface facing +x
    spun = np.concatenate([np.eye(4)[None], _poses(AXES[2], np.array([-3.0]))])  # +y to +x
    cos60 = np.cos(np.deg2rad(60.0))
    assert sweep_gain(surface, scores, spun, Reach(met * 0.04), 0.01, normals) == 1.5
    facing = Reach(met * 0.04, met, cos60)
    assert sweep_gain(surface, scores, spun, facing, 0.01, normals) == 0.5  # the flank only
    assert sweep_gain(surface, scores, spun, facing, 0.01) == 1.5  # no sample normals: any


def test_a_chooser_compares_facing_only_when_every_reach_point_has_a_normal() -> None:
    chooser = TurnChooser(1.0, 3.0, 1.25, 0.01, AXES, facing_deg=60.0)
    assert chooser.facing_cos == pytest.approx(0.5)
    with pytest.raises(ValueError, match="2 reach points but 1 normals"):
        chooser.note_reach(np.zeros((2, 3)), np.zeros((1, 3)))
    surface, up = np.array([[0.04, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    still = np.tile(np.eye(4), (len(chooser.ahead), 1, 1))
    chooser.note_reach(np.array([[0.04, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    chooser.choose(0.0, surface, np.ones(1), still, [still] * 6, up)
    assert chooser.log[-1][1] == 0.0  # the sample faces up where the finger met +x
    chooser.note_reach(np.array([[0.04, 0.0, 0.001]]))  # a reach point without a normal
    chooser.choose(1.0, surface, np.ones(1), still, [still] * 6, up)
    assert chooser.log[-1][1] == 1.0


@pytest.mark.parametrize("weight, expected", [(1.0, [0.0, 0.0, 1.0]), (0.0, [0.0, 0.0, -1.0])])
def test_a_place_already_offered_to_the_fingers_gains_its_weight(weight, expected) -> None:
    chooser = TurnChooser(1.0, 3.0, 1.25, 0.01, AXES, offered_weight=weight)
    # the finger at +x could press the -y flank before (object frame = world at the time)
    chooser.note_reach(np.array([[0.04, 0.0, 0.0]]), object_points=np.array([[0.0, -0.04, 0.0]]))
    surface = np.array([[0.0, 0.04, 0.0], [0.0, -0.04, 0.0]])
    still = np.tile(np.eye(4), (len(chooser.ahead), 1, 1))
    turns = [_poses(a, chooser.ahead) for a in chooser.candidates]
    # +z brings -y to the finger, -z brings +y; as good as each other until -y counts less
    chosen = chooser.choose(0.0, surface, np.ones(2), still, turns)
    np.testing.assert_allclose(chosen, expected)


def test_the_turn_that_brings_the_uncertain_cap_to_the_finger_replaces_the_plan() -> None:
    surface = _sphere()
    scores = (surface[:, 2] > 0.03).astype(float)  # only the +z cap is worth a touch
    chooser = _chooser()
    plan = _poses(AXES[2], chooser.ahead)  # about z: the cap stays on top
    turns = [_poses(a, chooser.ahead) for a in chooser.candidates]
    chosen = chooser.choose(0.0, surface, scores, plan, turns)
    # about +y, +z swings round to +x (where the finger is) within the 90 degrees of 3 s
    np.testing.assert_allclose(chosen, [0.0, 1.0, 0.0])
    t, kept, best, axis = chooser.log[-1]
    assert t == 0.0 and kept == 0.0 and best > 0 and axis == [0.0, 1.0, 0.0]


def test_given_axes_replace_the_candidates_for_one_comparison() -> None:
    # turn=advance offers one axis, the gait's next: +y brings the +z cap to the finger at
    # +x, +x keeps it away from it (the cap swings towards -y).
    surface = _sphere()
    scores = (surface[:, 2] > 0.03).astype(float)
    chooser = _chooser()
    plan = _poses(AXES[2], chooser.ahead)
    for axis, expected in ((AXES[1], AXES[1]), (AXES[0], None)):
        turn = [_poses(axis, chooser.ahead)]
        chosen = chooser.choose(0.0, surface, scores, plan, turn, axes=axis[None])
        if expected is None:
            assert chosen is None
        else:
            np.testing.assert_allclose(chosen, expected)
    with pytest.raises(ValueError, match="2 turns for 1 candidate axes"):
        chooser.choose(0.0, surface, scores, plan, [plan, plan], axes=AXES[:1])


def test_a_near_tie_keeps_the_plan() -> None:
    surface = _sphere()
    scores = np.ones(len(surface))
    chooser = _chooser(gain=1.25)
    turns = [_poses(a, chooser.ahead) for a in chooser.candidates]
    plan = _poses(AXES[2], chooser.ahead)  # as good as any turn on a uniform map
    assert chooser.choose(0.0, surface, scores, plan, turns) is None


def test_comparisons_wait_for_reach_and_for_check_s() -> None:
    chooser = TurnChooser(1.0, 3.0, 1.25, 0.01, AXES)
    assert not chooser.due(0.0)  # no reach noted yet
    chooser.note_reach(np.zeros((1, 3)))
    assert chooser.due(0.0)
    surface = _sphere(50)
    plan = _poses(AXES[2], chooser.ahead)
    chooser.choose(0.0, surface, np.zeros(50), plan, [plan] * 6)
    assert not chooser.due(0.9) and chooser.due(1.0)
    with pytest.raises(ValueError, match="6 candidate axes"):
        chooser.choose(1.0, surface, np.zeros(50), plan, [plan])


@pytest.mark.parametrize(
    "key, value",
    [
        ("turn", "spin"),
        ("turn_check_s", 0.0),
        ("turn_horizon_s", -1.0),
        ("turn_gain", 0.5),
        ("turn_facing_deg", 0.0),
        ("turn_facing_deg", 200.0),
        ("turn_offered_weight", 1.5),
    ],
)
def test_bad_turn_settings_are_value_errors_naming_the_key(key, value) -> None:
    with pytest.raises(ValueError, match=f"sensor.planner.*{key}"):
        TouchPlannerConfig(**{key: value})


def test_the_planner_turns_at_most_once_per_regrasp_gap_and_records_why() -> None:
    surface = _sphere()
    entropy = (surface[:, 2] > 0.03).astype(float)
    advice = TouchAdvice(surface, entropy, surface, TouchScoreConfig(novelty_weight=0.0), 3)
    planner = TouchPlanner(TouchPlannerConfig(turn="advice", regrasp_gap_s=2.0))
    assert not planner.turn_due(0.0)  # no advice yet
    planner.advice = advice
    planner.turns.note_reach(np.array([[0.04, 0.0, 0.0]]))
    assert planner.turn_due(0.0)
    turns = [_poses(a, planner.turns.ahead) for a in planner.turns.candidates]
    axis = planner.choose_turn(0.0, _poses(AXES[2], planner.turns.ahead), turns)
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0])
    assert planner.due_reason == "turn" and planner.last_regrasp_s == 0.0
    assert not planner.turn_due(1.5) and planner.turn_due(2.0)
    gait = TouchPlanner(TouchPlannerConfig(turn="gait"))
    assert gait.turns is None and not gait.turn_due(0.0)


def test_previews_move_no_horizon_and_a_turn_keeps_the_place_in_the_grasp() -> None:
    z, y, x = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]
    traj = ObjectTrajectory(np.zeros(3), z, alternate_axis=y, alternate_every_s=2.0, wobble_deg=0)
    traj.pose(1.0)
    traj.regrasp(1.0, x, np.array([0.02, 0.0, 0.0]))
    plan = traj.steady_poses(np.array([2.5, 6.0]))
    assert traj.horizon_s == 1.0  # a preview is not a pose given out
    np.testing.assert_allclose(plan[:, :3, :3], [traj.pose(2.5)[:3, :3], traj.pose(6.0)[:3, :3]])
    ahead = np.array([0.0, 1.0])
    preview = traj.turn_poses(6.0, z, ahead)
    np.testing.assert_allclose(preview[0], traj.steady_poses(np.array([6.0]))[0], atol=1e-12)
    k, start = traj.turn(6.0, z)
    assert start == 6.0 and traj.segment_axis(k) @ z == 1.0
    np.testing.assert_allclose(traj.segment_centre(k), [0.02, 0.0, 0.0])
    np.testing.assert_allclose(traj.pose(7.0)[:3, :3], preview[1][:3, :3], atol=1e-12)


def test_the_next_axis_is_the_alternations_and_follows_a_turn() -> None:
    z, y = np.eye(3)[2], np.eye(3)[1]
    traj = ObjectTrajectory(np.zeros(3), z, alternate_axis=y, alternate_every_s=2.0, wobble_deg=0)
    np.testing.assert_allclose(traj.next_axis(1.0), y)
    np.testing.assert_allclose(traj.next_axis(3.0), z)
    assert traj.horizon_s == 0.0  # a preview
    traj.pose(0.5)
    k, _ = traj.turn(0.5, y)  # the alternation moved forward: y from 0.5 s, then z
    np.testing.assert_allclose(traj.segment_axis(k), y)
    np.testing.assert_allclose(traj.next_axis(1.0), z)
    one = ObjectTrajectory(np.zeros(3), z)
    with pytest.raises(IndexError, match="one axis"):
        one.next_axis(1.0)


def test_advance_needs_an_alternation_to_move_forward() -> None:
    # The active policy's default turn rule; a rig turning about one axis has no next
    # stretch, so it is refused at construction, not at the first turn check.
    from neuralfeels_sem.sim.rig import SimRig
    from tests.sim.shapes import two_material_sphere

    sphere = two_material_sphere()
    with pytest.raises(ValueError, match="planner.turn=gait"):
        SimRig(sphere, planner=TouchPlanner(), alternate_axis=None)
    SimRig(sphere, planner=TouchPlanner(TouchPlannerConfig(turn="gait")), alternate_axis=None)
    SimRig(sphere, alternate_axis=None)  # the scripted gait: no planner, nothing to check
