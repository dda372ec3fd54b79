"""sensor.policy=active in the rig: best-scoring reachable touches, repeatable, regrasps when starved
or when the hotspot is out of the turn's reach.

The rig alone (no rendering), on a 4 cm two-material sphere, with fixed advice.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.sim.rig import SimRig
from neuralfeels_sem.sim.rig_params import GOOD_CONTACT_RAYS
from neuralfeels_sem.sim.touch_advice import TouchAdvice, TouchScoreConfig
from neuralfeels_sem.sim.touch_planner import TouchPlanner, TouchPlannerConfig
from tests.sim.shapes import two_material_sphere

MOTION = SimSensorConfig().rig_motion()
TOWARD = np.array([0.3, 1.0, 0.5]) / np.linalg.norm([0.3, 1.0, 0.5])


class TowardScore(TouchAdvice):
    """Advice that prefers points along one object-frame direction (score = 0.5 + 0.5 cos)."""

    def __init__(self) -> None:
        super().__init__(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)), TouchScoreConfig(), 0)

    def score(self, points: np.ndarray) -> np.ndarray:
        unit = points / np.linalg.norm(points, axis=1, keepdims=True)
        return 0.5 + 0.5 * unit @ TOWARD


def _active_rig(advice: TouchAdvice, seed: int = 0, **planner) -> SimRig:
    # The object turns as the gait turns it unless a test asks for chosen turns (the
    # planner's default, advance, would otherwise add turns to the regrasps tested here).
    planner.setdefault("turn", "gait")
    rig = SimRig(
        two_material_sphere(),
        seed=seed,
        planner=TouchPlanner(TouchPlannerConfig(**planner)),
        **MOTION,
    )
    rig.open()
    rig.planner.advice = advice
    return rig


def test_the_touch_is_the_best_scoring_candidate_that_verifies() -> None:
    rig = _active_rig(TowardScore())
    verify, checked = rig._verify, []

    def spy(finger, order, press, firm, world_T_object):
        contact = verify(finger, order, press, firm, world_T_object)
        scores = rig.planner.advice.score(np.array([c[4] for c in order]))
        full = np.array([-c[0] / GOOD_CONTACT_RAYS for c in order])
        assert (np.diff(scores * full) <= 1e-12).all()  # best score x contact first
        if contact is not None and len(checked) < 3:
            # the first candidate that verifies on its own is the one pressed
            first = next(c for c in order if verify(finger, [c], press, firm, world_T_object))
            again = verify(finger, [first], press, firm, world_T_object)
            np.testing.assert_allclose(again.point, contact.point, atol=1e-9)
            checked.append(finger)
        return contact

    rig._verify = spy
    for i in range(12):
        rig.state_at(i / 10)
    assert len(checked) == 3


def test_active_contacts_are_repeatable_per_seed_and_differ_from_the_gait() -> None:
    def contacts(rig: SimRig) -> list:
        out = []
        for i in range(20):
            state = rig.state_at(i / 10)
            out.append(
                [None if p is None else p.round(9).tolist() for p in state.contact_point.values()]
            )
        return out

    first, second = contacts(_active_rig(TowardScore())), contacts(_active_rig(TowardScore()))
    assert first == second
    scripted = SimRig(two_material_sphere(), seed=0, **MOTION)
    assert contacts(scripted) != first


def test_touches_lean_toward_the_advice() -> None:
    active, scripted = _active_rig(TowardScore()), SimRig(two_material_sphere(), seed=0, **MOTION)
    mean = {}
    for name, rig in (("active", active), ("scripted", scripted)):
        cos = []
        for i in range(30):
            state = rig.state_at(i / 10)
            for f, p in state.contact_point.items():
                if state.touching[f] and p is not None:
                    cos.append(p @ TOWARD / np.linalg.norm(p))
        mean[name] = float(np.mean(cos))
    assert mean["active"] > mean["scripted"] + 0.1, mean


def test_a_starved_planner_regrasps_and_the_rig_goes_on() -> None:
    # every point already touched and certain: nothing scores well anywhere
    sphere = two_material_sphere()
    surface = np.asarray(sphere.mesh.vertices)
    dull = TouchAdvice(surface, np.zeros(len(surface)), surface, TouchScoreConfig(), 0)
    rig = _active_rig(dull, regrasp_after=3, regrasp_gap_s=0.5)
    for i in range(25):
        rig.state_at(i / 10)
    assert rig.trajectory.regrasps
    t, axis, offset = rig.trajectory.regrasps[0]
    assert abs(axis @ rig.scene.world_T_palm[:3, 0]) < 0.9  # never about the palm normal
    assert np.linalg.norm(offset) <= rig.planner.config.max_offset_m + 1e-12
    rig.scene.step(100)
    assert rig.scene.warning_count == 0


def _heights_along_the_first_axis() -> tuple[np.ndarray, np.ndarray]:
    """The test sphere's vertices (object frame) and their heights at t=0 along the axis the
    object first turns about."""
    sphere = two_material_sphere()
    surface = np.asarray(sphere.mesh.vertices)
    probe = SimRig(sphere, seed=0, **MOTION)
    probe.open()
    pose, axis = probe.trajectory.pose(0.0), probe.trajectory.segment_axis(0)
    return surface, (surface @ pose[:3, :3].T) @ axis


def test_a_hotspot_beyond_the_turns_reach_starts_a_regrasp_soon() -> None:
    # Only the pole of the axis the object turns about first is uncertain: the turn never
    # brings it to the fingers, so the planner regrasps at its first advised contact.
    surface, height = _heights_along_the_first_axis()
    pole = int(np.argmax(height))
    entropy = np.zeros(len(surface))
    entropy[pole] = 1.0
    advice = TouchAdvice(surface, entropy, surface, TouchScoreConfig(), 0)
    # regrasp_after out of play: only the reach can start a regrasp here
    rig = _active_rig(advice, out_of_reach_m=0.01, regrasp_gap_s=0.5, regrasp_after=100)
    for i in range(10):
        rig.state_at(i / 10)
    assert rig.trajectory.regrasps and rig.trajectory.regrasps[0][0] < 1.0
    starved_only = _active_rig(advice, out_of_reach_m=None, regrasp_gap_s=0.5, regrasp_after=100)
    for i in range(10):
        starved_only.state_at(i / 10)
    assert not starved_only.trajectory.regrasps


def _closest_touch_s(rig: SimRig, point: np.ndarray, seconds: float, within_m: float):
    """The first time a finger touches within `within_m` of an object-frame point (or None)."""
    for i in range(int(seconds * 10)):
        state = rig.state_at(i / 10)
        for f, p in state.contact_point.items():
            if state.touching[f] and p is not None and np.linalg.norm(p - point) < within_m:
                return i / 10
    return None


def test_a_confirm_regrasp_brings_an_unconfirmed_reading_under_a_finger() -> None:
    # One reading to confirm, at the pole that faces the palm's normal at the start: the
    # first turn does not bring it to a finger within 6 s; a confirm regrasp does.
    sphere = two_material_sphere()
    surface = np.asarray(sphere.mesh.vertices)
    probe = SimRig(sphere, seed=0, **MOTION)
    probe.open()
    up = probe.trajectory.pose(0.0)[:3, :3].T @ probe.scene.world_T_palm[:3, 0]
    pole = surface[int(np.argmax(surface @ up))]
    score = TouchScoreConfig(confirm_weight=1.0)
    advice = TouchAdvice(surface, np.zeros(len(surface)), surface, score, 0, pole[None])
    aimed = _active_rig(advice, confirm_regrasp_after=2, regrasp_after=100)
    assert _closest_touch_s(aimed, pole, 6.0, 0.01) is not None
    assert aimed.regrasp_reasons and set(aimed.regrasp_reasons) == {"confirm"}
    plain = _active_rig(advice, regrasp_after=100)
    assert _closest_touch_s(plain, pole, 6.0, 0.01) is None
    assert not plain.trajectory.regrasps


def _share_on_cap(rig: SimRig, surface: np.ndarray, cap: np.ndarray) -> float:
    """The share of the rig's touching finger-frames over 4 s whose contact is on the cap."""
    on_cap = []
    for i in range(40):
        state = rig.state_at(i / 10)
        for f, p in state.contact_point.items():
            if state.touching[f] and p is not None:
                on_cap.append(cap[np.argmin(np.linalg.norm(surface - p, axis=1))])
    return float(np.mean(on_cap))


def test_a_chosen_turn_brings_the_uncertain_cap_to_the_fingers() -> None:
    # Only the cap round the first axis' pole is uncertain: the gait's turn about that axis
    # never brings it to a finger in 4 s; turn=advice turns the object so that it does, and
    # so does turn=advance, which starts the gait's second stretch (about y) early.
    surface, height = _heights_along_the_first_axis()
    cap = (height > 0.8 * height.max()).astype(float)
    advice = TouchAdvice(surface, cap, surface, TouchScoreConfig(novelty_weight=0.0), 0)
    share = {}
    for turn in ("gait", "advice", "advance"):
        rig = _active_rig(advice, turn=turn, regrasp_after=100)
        share[turn] = _share_on_cap(rig, surface, cap)
        if turn == "gait":
            assert not rig.trajectory.regrasps
        else:
            assert rig.regrasp_reasons and set(rig.regrasp_reasons) == {"turn"}
    assert share["gait"] == 0.0 and share["advice"] > 0.1 and share["advance"] > 0.1, share
    gait_axes = (MOTION["axis"], MOTION["alternate_axis"])  # advance turns about no other
    turned = [axis for _, axis, _ in rig.trajectory.regrasps]
    assert all(any(np.allclose(a, g) for g in gait_axes) for a in turned), turned


def test_a_chosen_turn_facing_the_fingers_still_brings_the_cap_to_them() -> None:
    # As above with the facing bound and offered places discounted: the rig passes the
    # mesh's normals at the screened touches and the touches' object-frame places.
    surface, height = _heights_along_the_first_axis()
    cap = (height > 0.8 * height.max()).astype(float)
    normals = surface / np.linalg.norm(surface, axis=1, keepdims=True)  # a sphere's
    advice = TouchAdvice(
        surface, cap, surface, TouchScoreConfig(novelty_weight=0.0), 0, normals=normals
    )
    rig = _active_rig(
        advice, turn="advice", regrasp_after=100, turn_facing_deg=60.0, turn_offered_weight=0.5
    )
    share = _share_on_cap(rig, surface, cap)
    turns = rig.planner.turns
    assert len(turns.offered) == len(turns.reach)  # every screened place, object frame
    met = np.asarray(turns.reach_normals)
    np.testing.assert_allclose(np.linalg.norm(met, axis=1), 1.0, atol=1e-6)
    assert set(rig.regrasp_reasons) == {"turn"} and share > 0.1
