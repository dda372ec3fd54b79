"""The touch advisor: a mapping-session observer that says where the hand should touch next.

It keeps the touches so far (the presses with a label, or every press: `novelty_from`)
and, when advice is asked for, samples the map's surface as it is after the latest mapped
frame (points of a sphere around the field's centre, moved onto the SDF's zero level by
Newton steps), takes the material branch's normalised entropy there, and packs both into a
TouchAdvice (sim/touch_advice.py) that scores object-frame points by uncertainty and
novelty. With sensor.policy=active the simulated sensor asks after every mapped frame and
presses where the advice scores highest; on any other rig (sensor=real, replay) the best
`top_k` surface points are written to the run as `touch_suggestions.json` at every scoring
pass and at the end (and drawn in `touch_suggestions.png`) for whatever moves the hand, and
the surface is sampled only then: sampling it after every frame took about a third of the
mapper thread's CPU time in a replay of the default run. The advisor only reads the field.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, get_args

import numpy as np
import torch

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import invert_pose
from neuralfeels_sem.fields.material_uncertainty import normalised_entropy
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.sim.touch_advice import TouchAdvice, TouchScoreConfig
from neuralfeels_sem.utils.atomic import atomic_write_text

log = logging.getLogger(__name__)

SUGGESTIONS_FILE = "touch_suggestions.json"
PROJECTION_STEPS = 4  # Newton steps onto the zero level (a trained SDF needs two)
ON_SURFACE_M = 0.003  # samples whose |sdf| stays above this after the steps are dropped
START_RADIUS = 0.6  # of the field's half-extent: the sphere the samples start on
NoveltySource = Literal["labelled", "pressed"]  # mapping.advisor.novelty_from
NOVELTY_SOURCES = get_args(NoveltySource)


@dataclass
class TouchAdvisorConfig:
    """`mapping.advisor`: how the map's touch advice is made and reported."""

    surface_points: int = 1024  # surface samples scored per refresh
    every_frames: int = 1  # advice asked for refreshes the samples this many mapped frames apart
    top_k: int = 8  # suggestions written to touch_suggestions.json
    # Which touches make a place less novel: `labelled` (a label that trains the map) or
    # `pressed` (any contact, abstentions too: a press the classifier could not read is
    # likely read no better the next time at the same place). A NoveltySource; typed `str`
    # because OmegaConf 2.3 rejects Literal annotations.
    novelty_from: str = "labelled"
    score: TouchScoreConfig = field(default_factory=TouchScoreConfig)

    def __post_init__(self) -> None:
        if not 16 <= self.surface_points <= 100_000:
            raise ValueError(
                f"mapping.advisor.surface_points={self.surface_points} must be in [16, 100000]"
            )
        if self.novelty_from not in NOVELTY_SOURCES:
            raise ValueError(
                f"mapping.advisor.novelty_from={self.novelty_from!r} must be labelled or pressed"
            )
        if self.every_frames < 1 or self.top_k < 1:
            raise ValueError(
                f"mapping.advisor: every_frames={self.every_frames} and top_k={self.top_k} must be >= 1"
            )


def sphere_directions(count: int) -> np.ndarray:
    """(count, 3) unit vectors spread evenly over the sphere (Fibonacci lattice)."""
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    phi = np.pi * (1.0 + 5**0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def surface_samples(
    semantic_field, directions: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points on the field's zero level (field frame), the material entropy there and the
    outward unit normals (the SDF's gradient at the last Newton step, a millimetre or less
    from the point: no extra pass)."""
    centre = semantic_field.center
    bound = semantic_field.bound
    x = centre + START_RADIUS * bound * torch.as_tensor(directions, dtype=centre.dtype).to(
        centre.device
    )
    for _ in range(PROJECTION_STEPS):
        sdf, grad = semantic_field.sdf_and_gradient(x, create_graph=False)
        step = sdf / grad.square().sum(dim=1).clamp_min(1e-6)
        x = (x - step[:, None] * grad).detach()
        x = torch.maximum(torch.minimum(x, centre + bound), centre - bound)
    with torch.no_grad():
        keep = semantic_field.sdf(x).abs() < ON_SURFACE_M
        x, normals = x[keep], torch.nn.functional.normalize(grad.detach()[keep], dim=1)
        entropy = (
            normalised_entropy(semantic_field.material_logits(x))
            if len(x)
            else torch.zeros(0, device=x.device)
        )
    return _numpy(x), _numpy(entropy), _numpy(normals)


def _numpy(t: torch.Tensor) -> np.ndarray:
    return t.double().cpu().numpy()


class TouchAdvisor:
    """Observer (pipeline/observers.py) that advises the sensor and writes suggestions.

    Args:
        config: mapping.advisor.
        sensor: the run's sensor; advised when it accepts advice (sensor.policy=active).
        out: the run directory (touch_suggestions.json / .png).
    """

    def __init__(self, config: TouchAdvisorConfig, sensor, out: Path) -> None:
        self.config, self.sensor, self.out = config, sensor, Path(out)
        self.directions = sphere_directions(config.surface_points)
        self.touched: list[np.ndarray] = []  # touches counted for novelty, field frame
        self.touched_labels: list[int] = []  # the class each was read as (-1: none)
        self.surface = np.zeros((0, 3))
        self.entropy = np.zeros(0)
        self.normals = np.zeros((0, 3))  # outward unit normals at the surface samples
        self.world_T_field = np.eye(4)  # the latest frame's object pose (the field's frame)
        self.unconfirmed = np.zeros((0, 3))  # readings to confirm, field frame
        self.mapped = 0
        self._advice: TouchAdvice | None = None
        self._pending: tuple[Frame, object] | None = None  # a frame mapped since, its mapper
        self._sampled_at: int | None = None  # `mapped` count the surface was sampled at

    @property
    def advice(self) -> TouchAdvice | None:
        """The advice after the latest mapped frame (None before the first), made when first
        asked for: a sensor that takes advice asks after every frame; on any other rig only
        the suggestions written at each scoring pass and at the end ask, so the surface is
        not sampled after frames nobody reads advice for."""
        if self._pending is not None:
            self._advice, self._pending = self._make_advice(*self._pending), None
        return self._advice

    def on_touches(self, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper) -> None:
        """A frame's touches (its gel centres, object frame) make their places less novel."""
        object_T_world = invert_pose(world_T_object)
        for finger, label in labels.items():
            reading = frame.tactile.get(finger)
            if reading is None or not self._counts(label):
                continue
            gel = reading.world_T_sensor @ np.array([0.0, 0.0, GEL_DISTANCE_M, 1.0])
            self.touched.append((object_T_world @ gel)[:3])
            self.touched_labels.append(int(label.label) if label.usable else -1)

    def on_frame(self, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper) -> None:
        self.on_touches(frame, labels, world_T_object, mapper)
        self.world_T_field = np.asarray(world_T_object, np.float64)
        self._pending = (frame, mapper)
        self.mapped += 1
        if getattr(self.sensor, "accepts_advice", False):
            self.sensor.advise(frame.index, self.advice)

    def _make_advice(self, frame: Frame, mapper) -> TouchAdvice:
        """The advice from the field as it is now, after `frame` (the latest mapped)."""
        due = self._sampled_at is None or self.mapped - self._sampled_at >= self.config.every_frames
        if due:
            self.surface, self.entropy, self.normals = surface_samples(
                mapper.field, self.directions
            )
            self._sampled_at = self.mapped
        # The sensor plans in its own object frame: the true one in sim (the field's frame
        # is the estimated one when the pose is tracked).
        truth = frame.gt_world_T_object
        sensor_T_field = np.eye(4) if truth is None else invert_pose(truth) @ self.world_T_field
        self.unconfirmed = self._unconfirmed(mapper)
        return TouchAdvice(
            _apply(sensor_T_field, self.surface),
            self.entropy,
            _apply(sensor_T_field, np.array(self.touched).reshape(-1, 3)),
            self.config.score,
            frame.index,
            _apply(sensor_T_field, self.unconfirmed),
            self.normals @ sensor_T_field[:3, :3].T,
            np.array(self.touched_labels, int),
        )

    def _unconfirmed(self, mapper) -> np.ndarray:
        """(K, 3) readings the vote left out that a press should confirm (field frame):
        for the confirm term and for a sensor's confirm regrasps; the vote they take costs
        milliseconds a frame, so not computed for nobody."""
        score = self.config.score
        if score.confirm_weight <= 0 and not getattr(self.sensor, "confirm_regrasps", False):
            return np.zeros((0, 3))
        points = mapper.memory.touches.unconfirmed_readings(score.confirm_m)
        return points.double().cpu().numpy()

    def _counts(self, label: TouchLabel) -> bool:
        """Whether this touch makes its place less novel (`novelty_from`)."""
        return label.contact if self.config.novelty_from == "pressed" else label.usable

    def on_scores(self, frame_index: int, scores: dict | None, mapper) -> None:
        self.write()

    def close(self) -> None:
        self.write(picture=True)

    def write(self, picture: bool = False) -> None:
        """touch_suggestions.json (and the picture): the best surface points to touch next."""
        latest = self.advice
        if latest is None:
            return
        advice = TouchAdvice(
            self.surface,
            self.entropy,
            np.array(self.touched).reshape(-1, 3),
            self.config.score,
            latest.frame_index,
            self.unconfirmed,
            labels=np.array(self.touched_labels, int),
        )
        points, scores = advice.suggestions(self.config.top_k)
        report = suggestions_report(advice, points, scores, self.world_T_field)
        report["novelty_from"] = self.config.novelty_from
        plan = getattr(self.sensor, "touch_plan", None)
        report["touch_plan"] = plan() if callable(plan) else None
        atomic_write_text(self.out / SUGGESTIONS_FILE, json.dumps(report, indent=1))
        if picture:
            from neuralfeels_sem.viz.touch_suggestions import draw_suggestions

            draw_suggestions(advice, points, self.out / "touch_suggestions.png")


def suggestions_report(
    advice: TouchAdvice, points: np.ndarray, scores: np.ndarray, world_T_object: np.ndarray
) -> dict:
    """The suggestions as JSON: object frame (the map's) and world frame at the latest pose."""
    uncertainty = advice.uncertainty(points)
    distance = advice.touch_distance(points)
    world = _apply(world_T_object, points)
    return {
        "after_frame": advice.frame_index,
        "frame": "object (the map's frame); world at the latest mapped pose",
        "touches_counted": len(advice.touched),
        "unconfirmed_readings": len(advice.unconfirmed),
        "surface_samples": len(advice.surface),
        "suggestions": [
            {
                "point_object_m": points[i].round(5).tolist(),
                "point_world_m": world[i].round(5).tolist(),
                "score": round(float(scores[i]), 4),
                "uncertainty": round(float(uncertainty[i]), 4),
                "touch_distance_m": None
                if not np.isfinite(distance[i])
                else round(float(distance[i]), 4),
            }
            for i in range(len(points))
        ],
        "world_T_object": np.asarray(world_T_object).round(6).tolist(),
    }


def _apply(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ pose[:3, :3].T + pose[:3, 3]


def touch_advisors(config: TouchAdvisorConfig, sensor, out: Path) -> list[TouchAdvisor]:
    """The map task's advisor: for an active sim policy, or any rig that is not simulated.

    A scripted sim run (the sensor says it takes no advice) gets none.
    """
    if getattr(sensor, "accepts_advice", None) is False:
        return []
    return [TouchAdvisor(config, sensor, out)]
