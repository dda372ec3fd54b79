"""Where to touch next (sensor.policy=active): rank reachable touches by the map's advice.

The map's advice (`TouchAdvice`, sim/touch_advice.py: the material branch's uncertainty,
novelty and readings to confirm) scores object-frame points.
`TouchPlanner` ranks the reachable touches the contact sampler screened (the postures
whose gel meets the object at touch-down time, sim/contact_sampler.py) by that score; the
sampler presses the best that its IK confirms. When the best reachable score stays below
`regrasp_below` for `regrasp_after` new contacts in a row, the planner turns and shifts
the object in the grasp (`regrasp_move`): the most uncertain, least touched part of the
map is brought to the fingers. With `confirm_regrasp_after`, a regrasp is also due when the
advice holds unconfirmed readings and no screened touch has come within `confirm_m` of one
for that many new contacts in a row: that regrasp brings the most uncertain of them to the
fingers instead (a part read once is left out of the map until a second press backs it,
and the turn the object is in may never bring it back). With `turn=advice` the planner also
chooses which way the object turns (TurnChooser, sim/turn_choice.py); with `turn=advance`
only when the gait's next stretch begins.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from neuralfeels_sem.sim.touch_advice import TouchAdvice
from neuralfeels_sem.sim.turn_choice import TurnChooser

TURN_MODES = ("gait", "advice", "advance")  # sensor.planner.turn


def check_turn_axes(
    turn: str, alternate_axis: Sequence[float] | None, name: str = "planner.turn"
) -> None:
    """turn=advance moves the gait's alternation forward, so the gait must alternate."""
    if turn == "advance" and alternate_axis is None:
        raise ValueError(
            f"{name}=advance (the active policy's default) moves the gait's alternation "
            f"forward: set an alternate_axis, or {name}=gait"
        )


@dataclass
class TouchPlannerConfig:
    """`sensor.planner`: how the active policy picks touches and when it regrasps."""

    candidates: int = 48  # reachable touches screened and scored per new contact
    # Rank by score x the touch's share of a full contact (its gel rays in contact, up to
    # the rig's GOOD_CONTACT_RAYS): a gel that meets the object with its edge leaves an
    # imprint the classifier often abstains on, and an unlabelled press teaches no material.
    weigh_by_contact: bool = True
    regrasp_below: float = 0.5  # a best reachable score under this starves the planner
    regrasp_after: int = 8  # new contacts in a row that starve before a regrasp
    regrasp_gap_s: float = 2.0  # at least this long between regrasps (the slide takes 1 s)
    # Also regrasp when the hotspot lies farther than this from the fingers' height along
    # the axis the object turns about: the current turn never brings it to them. null
    # (default): off; at 0.03 it regrasped 2-7 times a run and mapped worse
    # (docs/simulation.md).
    out_of_reach_m: float | None = None
    # Regrasp for an unconfirmed reading no screened touch could reach this many new
    # contacts in a row (see the module docstring). null (default): off.
    confirm_regrasp_after: int | None = None
    max_offset_m: float = 0.05  # the object's centre stays this close to the grasp centre
    keep_m: float = 0.02  # a regrasp brings the hotspot this close to the fingers' height
    axes: list[list[float]] = field(
        default_factory=lambda: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    )  # world-frame axes a regrasp (or a chosen turn, either way round) may turn it about
    # gait: the object turns as the scripted gait turns it (and as regrasps leave it);
    # advice: every turn_check_s the turn that brings the most touch score to the fingers
    # over turn_horizon_s replaces the plan when it gains turn_gain times as much
    # (sim/turn_choice.py); advance: the same comparison with one candidate, the gait's
    # next stretch begun now (its alternation moved forward, never reversed; needs
    # sensor.alternate_axis); at most one turn or regrasp per regrasp_gap_s. advance, the
    # default, has the higher lowest object on the development set (docs/simulation.md).
    turn: str = "advance"  # gait, advice or advance
    turn_check_s: float = 1.0
    turn_horizon_s: float = 3.0
    turn_gain: float = 1.25
    turn_reach_m: float = 0.01
    # A sample counts as brought only where it faces within this many degrees of the
    # surface the finger met at that place (its gel meets it head-on, not with its edge);
    # null: any facing (sim/turn_choice.py).
    turn_facing_deg: float | None = None
    # The share of its score a sample keeps once a finger could have pressed it (screened
    # there) and did not: below 1 a turn that only brings such places back gains less.
    turn_offered_weight: float = 0.3

    def __post_init__(self) -> None:
        if self.candidates < 1:
            raise ValueError(f"sensor.planner.candidates={self.candidates} must be >= 1")
        if not 0.0 <= self.regrasp_below <= 1.0:
            raise ValueError(f"sensor.planner.regrasp_below={self.regrasp_below} must be in [0, 1]")
        if self.regrasp_after < 1:
            raise ValueError(f"sensor.planner.regrasp_after={self.regrasp_after} must be >= 1")
        if self.out_of_reach_m is not None and self.out_of_reach_m <= 0:
            raise ValueError(
                f"sensor.planner.out_of_reach_m={self.out_of_reach_m} must be > 0 or null"
            )
        if self.confirm_regrasp_after is not None and self.confirm_regrasp_after < 1:
            raise ValueError(
                f"sensor.planner.confirm_regrasp_after={self.confirm_regrasp_after} "
                "must be >= 1 or null"
            )
        if self.regrasp_gap_s < 0 or self.max_offset_m < 0 or self.keep_m < 0:
            raise ValueError("sensor.planner: regrasp_gap_s, max_offset_m and keep_m must be >= 0")
        if self.turn not in TURN_MODES:
            raise ValueError(f"sensor.planner.turn={self.turn!r}: use {', '.join(TURN_MODES)}")
        if min(self.turn_check_s, self.turn_horizon_s, self.turn_reach_m) <= 0:
            raise ValueError(
                "sensor.planner: turn_check_s, turn_horizon_s and turn_reach_m must be > 0"
            )
        if self.turn_facing_deg is not None and not 0 < self.turn_facing_deg <= 180:
            raise ValueError(
                f"sensor.planner.turn_facing_deg={self.turn_facing_deg} must be in (0, 180] or null"
            )
        if not 0.0 <= self.turn_offered_weight <= 1.0:
            raise ValueError(
                f"sensor.planner.turn_offered_weight={self.turn_offered_weight} must be in [0, 1]"
            )
        if self.turn_gain < 1:
            raise ValueError(f"sensor.planner.turn_gain={self.turn_gain} must be >= 1")
        if not self.axes or any(len(a) != 3 or np.linalg.norm(a) < 1e-9 for a in self.axes):
            raise ValueError(
                f"sensor.planner.axes={self.axes} must be a non-empty list of non-zero [x, y, z]"
            )


class TouchPlanner:
    """Ranks reachable touches by the latest advice and decides when to regrasp."""

    def __init__(self, config: TouchPlannerConfig | None = None) -> None:
        self.config = config or TouchPlannerConfig()
        self.advice: TouchAdvice | None = None
        self.starved = 0  # new contacts in a row whose best reachable score was low
        self.last_regrasp_s = -np.inf
        self.unreached = 0  # new contacts in a row that could confirm no unconfirmed reading
        self.aim: np.ndarray | None = None  # the point the next regrasp brings to the fingers
        self.due_reason = ""  # why the latest regrasp was due: starved, away, confirm or turn
        self.choices: list[tuple[float, int, float]] = []  # (touch-down s, advice frame, score)
        c = self.config
        self.turns = (
            TurnChooser(
                c.turn_check_s,
                c.turn_horizon_s,
                c.turn_gain,
                c.turn_reach_m,
                c.axes,
                c.turn_facing_deg,
                c.turn_offered_weight,
            )
            if c.turn != "gait"
            else None
        )
        self._scored: tuple[TouchAdvice, np.ndarray] | None = None  # advice, its surface scores

    def rank(
        self, points: np.ndarray, contact: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Order (best first, ties keep the given order) and scores of candidate points.

        contact: (N,) each touch's share of a full contact in [0, 1]; with
        `weigh_by_contact` the order follows score x contact (the scores returned stay
        the advice's own). Without advice yet: the given order, scores all 1 (the
        sampler's own ranking).
        """
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if self.advice is None:
            return np.arange(len(points)), np.ones(len(points))
        scores = self.advice.score(points)
        key = scores
        if contact is not None and self.config.weigh_by_contact:
            contact = np.asarray(contact, np.float64).reshape(-1)
            if contact.shape != scores.shape or np.any((contact < 0) | (contact > 1)):
                raise ValueError(f"contact must be {len(scores)} shares in [0, 1]")
            key = scores * contact
        return np.lexsort((np.arange(len(points)), -key)), scores

    def confirm_reachable(self, points: np.ndarray) -> bool | None:
        """Whether a screened touch would confirm an unconfirmed reading (None: none to
        confirm, or no confirm regrasps)."""
        off = self.config.confirm_regrasp_after is None
        if off or self.advice is None or not len(self.advice.unconfirmed):
            return None
        return bool(self.advice.confirms(points).any())

    def note_choice(
        self,
        touchdown_s: float,
        best_score: float,
        hotspot_height_m: float | None = None,
        confirm_reachable: bool | None = None,
    ) -> bool:
        """Record a new contact's best reachable score; True when a regrasp is due.

        hotspot_height_m: the hotspot's distance from the fingers' height along the axis
        the object turns about now (None: unknown); beyond `out_of_reach_m` a regrasp is
        due as when starved. confirm_reachable: `confirm_reachable` of the screened
        touches; False for `confirm_regrasp_after` contacts in a row makes a regrasp due
        that aims at an unconfirmed reading.
        """
        frame = -1 if self.advice is None else self.advice.frame_index
        self.choices.append((float(touchdown_s), frame, float(best_score)))
        if self.advice is None:
            return False
        self.starved = self.starved + 1 if best_score < self.config.regrasp_below else 0
        self.unreached = self.unreached + 1 if confirm_reachable is False else 0
        reach = self.config.out_of_reach_m
        after = self.config.confirm_regrasp_after
        reasons = {  # the first that holds names the regrasp: a confirm regrasp aims elsewhere
            "confirm": after is not None and self.unreached >= after,
            "starved": self.starved >= self.config.regrasp_after,
            "away": reach is not None and hotspot_height_m is not None and hotspot_height_m > reach,
        }
        due = any(reasons.values()) and (
            touchdown_s - self.last_regrasp_s >= self.config.regrasp_gap_s
        )
        if due:
            self.aim = self._confirm_aim() if reasons["confirm"] else None
            self.due_reason = next(k for k, v in reasons.items() if v)
            self.starved, self.unreached = 0, 0
            self.last_regrasp_s = float(touchdown_s)
        return due

    def turn_due(self, t: float) -> bool:
        """Whether to compare turns at t (a chosen turn mode, advice there, no recent regrasp)."""
        gap_ok = t - self.last_regrasp_s >= self.config.regrasp_gap_s
        return self.turns is not None and self.advice is not None and gap_ok and self.turns.due(t)

    def choose_turn(
        self, t: float, plan: np.ndarray, turns: list[np.ndarray], axes: np.ndarray | None = None
    ) -> np.ndarray | None:
        """The axis to turn about from t, or None to keep the plan (see TurnChooser.choose)."""
        if self._scored is None or self._scored[0] is not self.advice:
            self._scored = (self.advice, self.advice.score(self.advice.surface))
        advice = self.advice
        axis = self.turns.choose(
            t, advice.surface, self._scored[1], plan, turns, advice.normals, axes
        )
        if axis is not None:
            self.last_regrasp_s, self.due_reason = float(t), "turn"
            self.starved, self.unreached = 0, 0
        return axis

    def _confirm_aim(self) -> np.ndarray:
        """The unconfirmed reading where the map is least sure (ties: the first)."""
        points = self.advice.unconfirmed
        return points[int(np.argmax(self.advice.uncertainty(points)))]

    def regrasp_move(
        self, world_T_object: np.ndarray, palm_up: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """New rotation axis and grasp offset (world, from the grasp centre) for the hotspot
        (or the unconfirmed reading a confirm regrasp aims at).

        The axis most aligned with the hotspot's direction from the object's centre (so that
        turning about it sweeps the hotspot's band past the fingers), the object slid along
        it until the hotspot lies within keep_m of the fingers' height (at most max_offset_m
        from the grasp centre). The slide keeps to the palm's plane and axes along the palm
        normal are skipped: the object never moves into the palm. None without advice.
        """
        if self.advice is None:
            return None
        spot, self.aim = (self.advice.hotspot() if self.aim is None else self.aim), None
        if spot is None:
            return None
        rel = world_T_object[:3, :3] @ spot  # hotspot from the object's centre, world
        axes = [np.asarray(a, float) / np.linalg.norm(a) for a in self.config.axes]
        up = np.asarray(palm_up, float) / np.linalg.norm(palm_up)
        usable = [a for a in axes if abs(a @ up) < 0.9] or axes
        axis = max(usable, key=lambda a: abs(a @ rel))
        height = float(axis @ rel)
        slide = -(height - np.sign(height) * min(abs(height), self.config.keep_m))
        offset = slide * axis
        offset -= (offset @ up) * up  # along the palm: never into it
        norm = np.linalg.norm(offset)
        if norm > self.config.max_offset_m:
            offset *= self.config.max_offset_m / norm
        return axis, offset
