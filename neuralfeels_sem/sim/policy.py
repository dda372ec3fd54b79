"""Finger gaiting for in-hand rotation: each finger touches, rides, lifts, moves ahead and re-touches.

The object turns under the hand (trajectory.py). Every finger runs the same cycle,
staggered by a quarter period so that about three fingers touch at any time:

  contact  (contact_fraction of the period): the gel lands on the planned point, pressed
           in by the finger's firmness, then holds its place while the surface slides
           under it (the rig keeps the press depth);
  lift     the gel backs off the surface by `lift_m` along the normal;
  transfer it swings, outside the object, to the next contact point;
  approach it presses onto the new point.

A new contact comes from a sampler (rig.py): a random posture of the finger whose gel,
pushed along its facing direction, meets the object at touch-down time; so every contact
is reachable by construction and over a run the touches sweep a band around the turning
object and beyond. The sampler is told where the other fingers are while the contact
lasts (`busy`), so that fingers keep clear of each other, and a finger that found no
room claims it: on an object too narrow for all fingers at once, they take turns.
Targets are given in the object frame and the rig (rig.py) turns them into joint angles
by IK; the plan depends on time, seed, trajectory and the order in which contacts were
asked for (repeatable run to run).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.sim.trajectory import ObjectTrajectory

# Stagger of the cycles (fraction of a period): neighbours never lift together.
PHASE_OFFSETS = {"index": 0.0, "middle": 0.5, "ring": 0.25, "thumb": 0.75}
LIFT_END, TRANSFER_END = 0.3, 0.7  # sub-phases of the non-contact part of a cycle


@dataclass(frozen=True)
class Contact:
    """A planned touch, in the object frame (it turns with the object)."""

    # (3,) where the gel centre is when the gel just touches (deepest reach 0); for a
    # head-on touch, the surface point in front of the gel centre
    point: np.ndarray
    normal: np.ndarray  # (3,) outward unit surface normal where the object reaches deepest
    pad: np.ndarray  # (3,) unit pad direction (sensor +z) the finger can reach there
    posture: np.ndarray | None = None  # (4,) the finger's joint angles at that touch


@dataclass(frozen=True)
class Busy:
    """Room another finger holds (a planned contact) or claims while a new contact lasts."""

    finger: str
    posture: np.ndarray  # (4,) its joint angles there
    firm: bool  # must be kept clear of; else only where the sampler can


@dataclass(frozen=True)
class FingerPlan:
    """One finger's target at one time, in the object frame."""

    gel_target: np.ndarray  # (3,) where the gel centre should be
    pad_direction: np.ndarray  # (3,) unit, desired sensor +z
    touching: bool  # in the contact phase (the gel should press in)
    cycle: int
    contact: Contact | None  # the point being touched (contact phase) or None


# (finger, touch-down time (s), rng, busy) -> a reachable Contact, or None
ContactSampler = Callable[[str, float, np.random.Generator, list[Busy]], "Contact | None"]


class GaitingPolicy:
    def __init__(
        self,
        trajectory: ObjectTrajectory,
        sampler: ContactSampler,
        press_depth_m: dict[str, float],
        period_s: float = 1.2,
        contact_fraction: float = 0.75,
        lift_m: float = 0.008,
        seed: int = 0,
        home: dict[str, np.ndarray] | None = None,
    ) -> None:
        if not 0.0 < contact_fraction < 1.0 or period_s <= 0 or lift_m <= 0:
            raise ValueError(
                f"need 0 < contact_fraction < 1, period_s > 0, lift_m > 0; got {contact_fraction}, {period_s}, {lift_m}"
            )
        self.trajectory, self.sampler = trajectory, sampler
        self.press = dict(press_depth_m)
        self.period, self.contact_fraction, self.lift = period_s, contact_fraction, lift_m
        self.seed = seed
        # finger -> joint posture (4,) whose room it claims when it holds no planned contact:
        # its home posture, then its latest contact, or a touch the sampler found blocked
        self.claims = dict(home or {})
        self.last_touch: dict[str, float] = {}  # finger -> start of its latest planned contact
        self._contacts: dict[tuple[str, int], Contact | None] = {}
        self.broken: set[tuple[str, int]] = set()  # (finger, cycle) whose contact the rig gave up
        # Where a finger actually touched last in a cycle (the rig lets the surface slide under
        # a touching finger); the lift starts from there.
        self.last_contact: dict[tuple[str, int], Contact] = {}

    def cycle_and_phase(self, finger: str, t: float) -> tuple[int, float]:
        s = t / self.period + PHASE_OFFSETS[finger]
        k = int(np.floor(s))
        return k, s - k

    def contact(self, finger: str, cycle: int) -> Contact | None:
        """The touch a finger makes in a cycle (cached; None if the sampler found none)."""
        key = (finger, cycle)
        if key not in self._contacts:
            c = self._contacts[key] = self._choose(finger, cycle)
            if c is not None:
                self.last_touch[finger] = self.touchdown(finger, cycle)
                if c.posture is not None:
                    self.claims[finger] = c.posture
        return self._contacts[key]

    def window(self, finger: str, cycle: int) -> tuple[float, float]:
        """Time span (s) a finger spends near its contact of `cycle`.

        From the start of its approach to the end of the transfer that takes it away.
        """
        rest = 1.0 - self.contact_fraction
        base = cycle - PHASE_OFFSETS[finger]
        start = base - rest * (1.0 - TRANSFER_END)
        end = base + self.contact_fraction + rest * TRANSFER_END
        return start * self.period, end * self.period

    def touchdown(self, finger: str, cycle: int) -> float:
        """Start (s) of a finger's contact phase in `cycle` (not before 0)."""
        return max((cycle - PHASE_OFFSETS[finger]) * self.period, 0.0)

    def busy(self, finger: str, cycle: int) -> list[Busy]:
        """Where the other fingers are while this finger's contact of `cycle` lasts.

        Firm: their planned contacts that overlap it in time. A claim, for a finger without
        a planned contact at the end of this one (not planned yet, or none found): its
        latest contact (fingers come back near where they touched, as the object turns
        under them) or, if the sampler found its touches blocked by neighbours, the best of
        those. A claim is firm if its finger has gone longer without a contact than this
        one: on an object too narrow for all fingers at once, they take turns.
        """
        start, end = self.window(finger, cycle)
        found: list[Busy] = []
        for other in self.press:
            if other == finger:
                continue
            holds_to_end = False
            for k in range(cycle - 2, cycle + 3):  # windows are about one period long
                c = self._contacts.get((other, k))
                if c is None or c.posture is None:
                    continue
                s, e = self.window(other, k)
                if s < end and start < e:
                    found.append(Busy(other, c.posture, True))
                    holds_to_end |= e >= end
            claim = self.claims.get(other)
            if not holds_to_end and claim is not None:
                hungrier = self.last_touch.get(other, -np.inf) < self.last_touch.get(
                    finger, -np.inf
                )
                found.append(Busy(other, claim, hungrier))
        return found

    def _choose(self, finger: str, cycle: int) -> Contact | None:
        rng = np.random.default_rng([self.seed, FINGERS.index(finger), cycle + 1_000_000])
        return self.sampler(finger, self.touchdown(finger, cycle), rng, self.busy(finger, cycle))

    def _pressed(self, finger: str, c: Contact) -> np.ndarray:
        return c.point + self.press[finger] * c.pad

    def _lifted(self, c: Contact) -> np.ndarray:
        return c.point - self.lift * c.pad

    def plan(self, finger: str, t: float, hover: np.ndarray, hover_pad: np.ndarray) -> FingerPlan:
        """Target of `finger` at time t; `hover` and `hover_pad` (object frame) where no contact exists."""
        k, phase = self.cycle_and_phase(finger, t)
        planned = self.contact(finger, k)
        now = self.last_contact.get((finger, k), planned)
        if (finger, k) in self.broken:
            # Given up: wait at the hover place (fixed in the world) rather than follow the
            # turning object, which would drag the finger to the end of its reach where the
            # object turns into it.
            now = None
        if phase < self.contact_fraction:
            if now is None:
                return FingerPlan(hover, hover_pad, False, k, None)
            return FingerPlan(self._pressed(finger, now), now.pad, True, k, now)
        u = (phase - self.contact_fraction) / (1.0 - self.contact_fraction)
        nxt = self.contact(finger, k + 1)
        start = self._lifted(now) if now is not None else hover
        start_dir = now.pad if now is not None else hover_pad
        end = self._lifted(nxt) if nxt is not None else hover
        end_dir = nxt.pad if nxt is not None else hover_pad
        if u < LIFT_END:
            base = self._pressed(finger, now) if now is not None else hover
            return FingerPlan(_lerp(base, start, u / LIFT_END), start_dir, False, k, None)
        if u < TRANSFER_END:
            w = (u - LIFT_END) / (TRANSFER_END - LIFT_END)
            return FingerPlan(
                _swing(start, end, w, self.lift), _nlerp(start_dir, end_dir, w), False, k, None
            )
        w = (u - TRANSFER_END) / (1.0 - TRANSFER_END)
        target = self._pressed(finger, nxt) if nxt is not None else hover
        return FingerPlan(_lerp(end, target, w), end_dir, False, k, None)


def _lerp(a: np.ndarray, b: np.ndarray, w: float) -> np.ndarray:
    return (1.0 - w) * a + w * b


def _nlerp(a: np.ndarray, b: np.ndarray, w: float) -> np.ndarray:
    v = _lerp(a, b, w)
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else b


def _swing(a: np.ndarray, b: np.ndarray, w: float, bump: float) -> np.ndarray:
    """Move from a to b around the object centre (origin), bulging outward, never through it."""
    ra, rb = np.linalg.norm(a), np.linalg.norm(b)
    direction = _nlerp(a / max(ra, 1e-9), b / max(rb, 1e-9), w)
    return direction * (_lerp(ra, rb, w) + bump * np.sin(np.pi * w))
