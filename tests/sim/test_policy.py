"""The gaiting schedule: staggered contact phases, exact press targets, transfers outside the object."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sim.policy import Busy, Contact, GaitingPolicy
from neuralfeels_sem.sim.trajectory import ObjectTrajectory

RADIUS = 0.04
PRESS = {"index": 0.0015, "middle": 0.0015, "ring": 0.0015, "thumb": 0.0007}


def sphere_sampler(
    finger: str, touchdown_s: float, rng: np.random.Generator, busy: list[Busy]
) -> Contact:
    """A random point on a sphere of RADIUS around the object origin, touched head-on."""
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    return Contact(point=RADIUS * u, normal=u, pad=-u)


def make_policy(contact_fraction: float = 0.75) -> GaitingPolicy:
    traj = ObjectTrajectory(np.zeros(3), (0, 0, 1), speed_deg_s=30.0)
    return GaitingPolicy(
        traj, sphere_sampler, PRESS, period_s=1.2, contact_fraction=contact_fraction, seed=0
    )


def test_contact_phase_targets_press_by_each_fingers_firmness() -> None:
    policy = make_policy()
    hover, pad = np.array([0.1, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    for finger in FINGERS:
        k, phase = policy.cycle_and_phase(finger, 3.0)
        t = 3.0 + (0.3 - phase) * 1.2 if phase >= 0.75 else 3.0  # inside a contact phase
        plan = policy.plan(finger, t, hover, pad)
        assert plan.touching
        c = plan.contact
        np.testing.assert_allclose(plan.gel_target, c.point + PRESS[finger] * c.pad, atol=1e-15)
        np.testing.assert_allclose(plan.pad_direction, c.pad)
        # The gel centre lies inside the sphere by exactly the press depth.
        assert np.linalg.norm(plan.gel_target) == pytest.approx(RADIUS - PRESS[finger], abs=1e-12)


def test_staggered_cycles_keep_three_fingers_in_contact_phase() -> None:
    policy = make_policy()
    hover, pad = np.array([0.1, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    times = np.arange(0.0, 6.0, 0.01)
    touching = np.array([[policy.plan(f, t, hover, pad).touching for f in FINGERS] for t in times])
    assert touching.sum(axis=1).min() >= 2
    assert touching.sum(axis=1).mean() == pytest.approx(3.0, abs=0.05)
    for column in touching.T:
        assert column.mean() == pytest.approx(0.75, abs=0.02)
        # Each finger breaks and re-makes contact once per 1.2 s period.
        remakes = np.count_nonzero(~column[:-1] & column[1:])
        assert remakes in (4, 5)


def test_transfers_stay_outside_the_object() -> None:
    policy = make_policy()
    hover, pad = np.array([0.1, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    for finger in FINGERS:
        for t in np.arange(0.0, 6.0, 0.005):
            plan = policy.plan(finger, t, hover, pad)
            if not plan.touching:
                # At most the press depth inside (lifting off / landing), never through the object.
                assert np.linalg.norm(plan.gel_target) >= RADIUS - PRESS[finger] - 1e-9


def test_plan_is_repeatable_and_a_broken_contact_waits_at_the_hover_place() -> None:
    a, b = make_policy(), make_policy()
    hover, pad = np.array([0.1, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    np.testing.assert_allclose(
        a.plan("ring", 2.0, hover, pad).gel_target, b.plan("ring", 2.0, hover, pad).gel_target
    )
    k, _ = a.cycle_and_phase("index", 0.1)
    assert a.plan("index", 0.1, hover, pad).touching
    a.broken.add(("index", k))
    plan = a.plan("index", 0.1, hover, pad)
    assert not plan.touching
    np.testing.assert_allclose(plan.gel_target, hover)
    np.testing.assert_allclose(plan.pad_direction, pad)
    # and the lift after the contact phase starts from there, not from the given-up touch
    lifting = a.plan("index", (k + 0.8) * a.period, hover, pad)
    assert not lifting.touching
    np.testing.assert_allclose(lifting.gel_target, hover)


@pytest.mark.parametrize("fraction", [0.0, 1.0])
def test_bad_contact_fraction_is_a_value_error(fraction: float) -> None:
    with pytest.raises(ValueError, match="contact_fraction"):
        make_policy(fraction)


def test_busy_lists_overlapping_contacts_firm_and_claims_of_hungrier_fingers() -> None:
    """Fingers keep clear of the neighbours' planned touches; one left without a touch claims room."""
    postures = {f: np.full(4, float(i)) for i, f in enumerate(FINGERS)}
    found = {"index": None, "middle": "touch", "ring": "touch", "thumb": "touch"}
    seen: dict[str, list[Busy]] = {}

    def sampler(finger: str, touchdown_s: float, rng: np.random.Generator, busy: list[Busy]):
        seen[finger] = busy
        if found[finger] is None:
            return None
        u = np.array([1.0, 0.0, 0.0])
        return Contact(RADIUS * u, u, -u, posture=postures[finger])

    home = {f: -postures[f] for f in FINGERS}
    traj = ObjectTrajectory(np.zeros(3), (0, 0, 1), speed_deg_s=30.0)
    policy = GaitingPolicy(traj, sampler, PRESS, seed=0, home=home)
    hover, pad = np.array([0.1, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    for finger in ("middle", "index"):
        policy.plan(finger, 0.0, hover, pad)
    # The index, planned after the middle finger, must keep clear of its touch.
    firm = [b for b in seen["index"] if b.firm]
    assert any(b.finger == "middle" and b.posture is postures["middle"] for b in firm)
    # The index found nothing. The ring has not touched yet either: for it the index's claim
    # (its home posture) is only a preference.
    policy.plan("ring", 0.0, hover, pad)
    claims = [b for b in seen["ring"] if b.finger == "index"]
    assert len(claims) == 1 and not claims[0].firm
    np.testing.assert_array_equal(claims[0].posture, home["index"])
    # The middle finger has touched, the index has not: for the middle finger's next touch
    # the index's claim is firm, so that the index gets a turn.
    policy.plan("middle", 1.0, hover, pad)
    claims = [b for b in seen["middle"] if b.finger == "index"]
    assert claims and all(b.firm for b in claims)
