"""Finger gaiting for in-hand rotation: each finger touches, rides, lifts, moves ahead and re-touches.

The object turns under the hand (trajectory.py). Every finger runs the same cycle,
staggered by a quarter period so that about three fingers touch at any time:

  contact  (contact_fraction of the period): the gel lands on the planned point, pressed
           in by the finger's firmness, then holds its place while the surface slides
           under it (the rig keeps the press depth);
  lift     the gel backs off the surface by `lift_m` along the normal;
  transfer it swings, outside the object, to the next contact point;
  approach it presses onto the new point.

A new contact point comes from a sampler (rig.py): a random posture near the finger's
natural one, whose pad, pushed along its facing direction, meets the object at
touch-down time; so every contact is reachable by construction and over a run the
touches sweep a band around the turning object and beyond. The plan is a pure function of time, seed and trajectory: targets are
given in the object frame and the rig (rig.py) turns them into joint angles by IK.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from neuralfeels_sem.sensors.frame import FINGERS
from neuralfeels_sem.sim.trajectory import ObjectTrajectory

# Stagger of the cycles (fraction of a period): neighbours never lift together.
PHASE_OFFSETS = {"index": 0.0, "middle": 0.5, "ring": 0.25, "thumb": 0.75}
LIFT_END, TRANSFER_END = 0.3, 0.7  # sub-phases of the non-contact part of a cycle


@dataclass(frozen=True)
class Contact:
    """A planned touch, in the object frame (it turns with the object)."""

    point: np.ndarray  # (3,) surface point in front of the gel centre
    normal: np.ndarray  # (3,) outward unit surface normal there
    pad: np.ndarray  # (3,) unit pad direction (sensor +z) the finger can reach there
    posture: np.ndarray | None = None  # (4,) joint angles from which the IK reached it


@dataclass(frozen=True)
class FingerPlan:
    """One finger's target at one time, in the object frame."""

    gel_target: np.ndarray  # (3,) where the gel centre should be
    pad_direction: np.ndarray  # (3,) unit, desired sensor +z
    touching: bool  # in the contact phase (the gel should press in)
    cycle: int
    contact: Contact | None  # the point being touched (contact phase) or None


# (finger, world_T_object at touch-down, rng) -> a reachable Contact, or None
ContactSampler = Callable[[str, np.ndarray, np.random.Generator], "Contact | None"]


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
    ) -> None:
        if not 0.0 < contact_fraction < 1.0 or period_s <= 0 or lift_m <= 0:
            raise ValueError(
                f"need 0 < contact_fraction < 1, period_s > 0, lift_m > 0; got {contact_fraction}, {period_s}, {lift_m}"
            )
        self.trajectory, self.sampler = trajectory, sampler
        self.press = dict(press_depth_m)
        self.period, self.contact_fraction, self.lift = period_s, contact_fraction, lift_m
        self.seed = seed
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
        """The surface point a finger touches in a cycle (cached; None if its ray misses)."""
        key = (finger, cycle)
        if key not in self._contacts:
            self._contacts[key] = self._choose(finger, cycle)
        return self._contacts[key]

    def _choose(self, finger: str, cycle: int) -> Contact | None:
        touchdown = max((cycle - PHASE_OFFSETS[finger]) * self.period, 0.0)
        rng = np.random.default_rng([self.seed, FINGERS.index(finger), cycle + 1_000_000])
        return self.sampler(finger, self.trajectory.pose(touchdown), rng)

    def _pressed(self, finger: str, c: Contact) -> np.ndarray:
        return c.point + self.press[finger] * c.pad

    def _lifted(self, c: Contact) -> np.ndarray:
        return c.point - self.lift * c.pad

    def plan(self, finger: str, t: float, hover: np.ndarray, hover_pad: np.ndarray) -> FingerPlan:
        """Target of `finger` at time t; `hover` and `hover_pad` (object frame) where no contact exists."""
        k, phase = self.cycle_and_phase(finger, t)
        planned = self.contact(finger, k)
        now = self.last_contact.get((finger, k), planned)
        if phase < self.contact_fraction:
            if now is None:
                return FingerPlan(hover, hover_pad, False, k, None)
            if (finger, k) in self.broken:
                return FingerPlan(self._lifted(now), now.pad, False, k, None)
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
