"""The touch advisor: surface samples of the field, advice handed to the sensor, suggestions written."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.frame import Frame, TactileReading
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.pipeline.touch_advisor import (
    SUGGESTIONS_FILE,
    TouchAdvisor,
    TouchAdvisorConfig,
    surface_samples,
    touch_advisors,
)

RADIUS = 0.03


class SphereField(torch.nn.Module):
    """A 3 cm sphere: fabric (certain) above z = 0, an even guess between 4 classes below."""

    def __init__(self) -> None:
        super().__init__()
        self.bound = 0.06
        self.register_buffer("center", torch.zeros(3, dtype=torch.float64))

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return x.norm(dim=1) - RADIUS

    def sdf_and_gradient(self, x: torch.Tensor, create_graph: bool = False):
        return self.sdf(x), x / x.norm(dim=1, keepdim=True)

    def material_logits(self, x: torch.Tensor) -> torch.Tensor:
        logits = torch.zeros(len(x), 4, dtype=x.dtype)
        logits[x[:, 2] > 0, 2] = 20.0
        return logits


class Mapper:
    field = SphereField()

    def __init__(self) -> None:
        self.memory = EmptyMemory()


class EmptyMemory:
    """A mapper memory with no touches (so no readings to confirm)."""

    def __init__(self) -> None:
        from neuralfeels_sem.mapping.touch_memory import TouchBuffer

        self.touches = TouchBuffer(torch.device("cpu"), None)


class AdvisedSensor:
    accepts_advice = True

    def __init__(self) -> None:
        self.advised = []

    def advise(self, frame_index, advice) -> None:
        self.advised.append((frame_index, advice))

    def touch_plan(self) -> dict:
        return {"policy": "active", "regrasps": []}


def _frame(index: int) -> Frame:
    """The index finger's gel touches the sphere's top (object frame = world)."""
    world_T_sensor = np.eye(4)
    world_T_sensor[:3, 3] = [0.0, 0.0, RADIUS - GEL_DISTANCE_M]
    reading = TactileReading(
        "index", np.zeros((320, 240, 3), np.uint8), world_T_sensor, DIGIT_INTRINSICS
    )
    return Frame(index, index / 10, np.eye(4), {"index": reading}, gt_world_T_object=np.eye(4))


def test_surface_samples_lie_on_the_zero_level_with_the_branch_entropy_and_normals() -> None:
    directions = np.random.default_rng(0).normal(size=(200, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points, entropy, normals = surface_samples(SphereField(), directions)
    assert len(points) == 200 and normals.shape == (200, 3)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), RADIUS, atol=1e-6)
    np.testing.assert_allclose(normals, points / RADIUS, atol=1e-6)  # outward, unit
    np.testing.assert_allclose(entropy[points[:, 2] > 0.001], 0.0, atol=1e-6)
    np.testing.assert_allclose(entropy[points[:, 2] < -0.001], 1.0, atol=1e-6)


def test_advice_reaches_the_sensor_and_suggestions_point_at_the_uncertain_half(tmp_path) -> None:
    sensor = AdvisedSensor()
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=256, top_k=4), sensor, tmp_path)
    for i in range(3):
        label = TouchLabel("index", True, 2, 0.99)
        advisor.on_frame(_frame(i), {"index": label}, np.eye(4), Mapper())
    assert [i for i, _ in sensor.advised] == [0, 1, 2]
    advice = sensor.advised[-1][1]
    assert advice.normals.shape == advice.surface.shape  # for a chosen turn's facing
    advice = sensor.advised[-1][1]
    np.testing.assert_allclose(advice.touched, [[0.0, 0.0, RADIUS]] * 3, atol=1e-12)
    advisor.on_scores(2, None, Mapper())
    advisor.close()
    report = json.loads((tmp_path / SUGGESTIONS_FILE).read_text())
    assert report["after_frame"] == 2 and report["touches_counted"] == 3
    assert report["novelty_from"] == "labelled"
    assert len(report["suggestions"]) == 4
    scores = [s["score"] for s in report["suggestions"]]
    assert scores == sorted(scores, reverse=True)
    # the unknown lower half comes first; the touched, certain top never
    assert all(s["point_object_m"][2] < 0 for s in report["suggestions"])
    assert report["touch_plan"] == {"policy": "active", "regrasps": []}
    assert (tmp_path / "touch_suggestions.png").stat().st_size > 0


def test_a_rig_samples_the_surface_only_when_suggestions_are_written(tmp_path, monkeypatch):
    """Without a sensor that takes advice (sensor=real, replay) nothing reads the advice
    between the written suggestions: three frames mapped, one sampling, at the write."""
    import neuralfeels_sem.pipeline.touch_advisor as advisor_module

    calls = []
    sample = advisor_module.surface_samples
    monkeypatch.setattr(advisor_module, "surface_samples", lambda *a: calls.append(1) or sample(*a))
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=256, top_k=4), None, tmp_path)
    label = TouchLabel("index", True, 2, 0.99)
    for i in range(3):
        advisor.on_frame(_frame(i), {"index": label}, np.eye(4), Mapper())
    assert calls == []
    advisor.on_scores(2, None, Mapper())
    advisor.close()  # nothing mapped since: the same samples
    assert len(calls) == 1
    report = json.loads((tmp_path / SUGGESTIONS_FILE).read_text())
    assert report["after_frame"] == 2 and report["touches_counted"] == 3
    assert all(s["point_object_m"][2] < 0 for s in report["suggestions"])
    advisor.on_frame(_frame(3), {"index": label}, np.eye(4), Mapper())
    advisor.write()
    assert (
        len(calls) == 2
        and json.loads((tmp_path / SUGGESTIONS_FILE).read_text())["after_frame"] == 3
    )


def test_every_frames_spaces_the_samplings_of_an_advised_sensor(tmp_path, monkeypatch):
    import neuralfeels_sem.pipeline.touch_advisor as advisor_module

    calls = []
    sample = advisor_module.surface_samples
    monkeypatch.setattr(advisor_module, "surface_samples", lambda *a: calls.append(1) or sample(*a))
    sensor = AdvisedSensor()
    config = TouchAdvisorConfig(surface_points=64, every_frames=2)
    advisor = TouchAdvisor(config, sensor, tmp_path)
    for i in range(5):
        advisor.on_frame(_frame(i), {}, np.eye(4), Mapper())
    assert len(sensor.advised) == 5 and len(calls) == 3  # after frames 0, 2 and 4


def test_a_touch_without_a_usable_label_is_not_counted(tmp_path) -> None:
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=64), AdvisedSensor(), tmp_path)
    advisor.on_frame(_frame(0), {"index": TouchLabel("index", False)}, np.eye(4), Mapper())
    abstained = TouchLabel("index", True, 2, 0.4, low_confidence=True)
    advisor.on_frame(_frame(1), {"index": abstained}, np.eye(4), Mapper())
    assert advisor.touched == []


def test_novelty_from_pressed_counts_an_abstained_press_but_not_a_miss(tmp_path) -> None:
    config = TouchAdvisorConfig(surface_points=64, novelty_from="pressed")
    advisor = TouchAdvisor(config, AdvisedSensor(), tmp_path)
    advisor.on_frame(_frame(0), {"index": TouchLabel("index", False)}, np.eye(4), Mapper())
    abstained = TouchLabel("index", True, 2, 0.4, low_confidence=True)
    advisor.on_frame(_frame(1), {"index": abstained}, np.eye(4), Mapper())
    np.testing.assert_allclose(advisor.touched, [[0.0, 0.0, RADIUS]], atol=1e-12)
    assert advisor.advice.touch_distance(np.array([[0.0, 0.0, RADIUS]]))[0] < 1e-9
    assert advisor.touched_labels == [-1]  # no material for the border term


def test_each_counted_touch_keeps_the_label_it_was_read_as(tmp_path) -> None:
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=64), AdvisedSensor(), tmp_path)
    advisor.on_frame(_frame(0), {"index": TouchLabel("index", True, 2, 0.99)}, np.eye(4), Mapper())
    advisor.on_frame(_frame(1), {"index": TouchLabel("index", True, 1, 0.99)}, np.eye(4), Mapper())
    assert advisor.touched_labels == [2, 1]


def test_touches_of_frames_not_mapped_count_without_new_advice(tmp_path) -> None:
    """sensor.pace=realtime maps the touches of overtaken frames (on_touches): their places
    are touched, and advice waits for the next mapped frame."""
    sensor = AdvisedSensor()
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=64), sensor, tmp_path)
    advisor.on_touches(_frame(0), {"index": TouchLabel("index", True, 2, 0.99)}, np.eye(4), None)
    np.testing.assert_allclose(advisor.touched, [[0.0, 0.0, RADIUS]], atol=1e-12)
    assert sensor.advised == [] and advisor.advice is None


def test_an_unknown_novelty_source_is_refused() -> None:
    with pytest.raises(ValueError, match="mapping.advisor.novelty_from"):
        TouchAdvisorConfig(novelty_from="seen")


def test_only_an_advised_or_unsimulated_sensor_gets_an_advisor(tmp_path) -> None:
    class Scripted:
        accepts_advice = False

    class Real:
        pass

    config = TouchAdvisorConfig()
    assert touch_advisors(config, Scripted(), tmp_path) == []
    assert len(touch_advisors(config, Real(), tmp_path)) == 1
    assert len(touch_advisors(config, AdvisedSensor(), tmp_path)) == 1


def test_a_reading_left_out_by_the_vote_draws_the_next_press_with_the_confirm_term(
    tmp_path,
) -> None:
    from neuralfeels_sem.mapping.label_vote import LabelVote
    from neuralfeels_sem.mapping.touch_memory import TouchBuffer
    from neuralfeels_sem.sim.touch_advice import TouchScoreConfig

    vote = LabelVote(radius=0.01, min_neighbours=3, min_agreement=0.25, min_support=1,
                     press_gap=0, support_radius=0.04, steady_frames=0, press_reach=None)  # fmt: skip
    side = [0.0, (RADIUS**2 - 0.01**2) ** 0.5, 0.01]  # on the certain upper half
    lone = torch.tensor([side] * 4, dtype=torch.float32)  # fabric read once there

    class Memory:
        touches = TouchBuffer(torch.device("cpu"), vote)

    Memory.touches.add(lone, torch.tensor([0.0, 1.0, 0.0]), 2, 0.9, finger="ring")
    mapper = Mapper()
    mapper.memory = Memory()
    score = TouchScoreConfig(confirm_weight=0.5)
    advisor = TouchAdvisor(TouchAdvisorConfig(surface_points=256, score=score), None, tmp_path)
    advisor.on_frame(_frame(0), {}, np.eye(4), mapper)
    advice = advisor.advice
    np.testing.assert_allclose(advice.unconfirmed, lone[:1].numpy(), atol=1e-7)
    at_reading, beside = advice.score(np.array([side, [0.0, -side[1], side[2]]]))
    assert beside == pytest.approx(0.5)  # certain, but fully novel
    assert at_reading == pytest.approx(0.75)  # lifted half the way to 1
    assert advice.confirms(np.array([[0.0, side[1], 0.021]]))[0] == 0.0  # past confirm_m
    plain = TouchAdvisor(TouchAdvisorConfig(surface_points=256), None, tmp_path)
    plain.on_frame(_frame(0), {}, np.eye(4), Mapper())  # off: the mapper's memory is not read
    assert len(plain.advice.unconfirmed) == 0
    # a sensor that regrasps to confirm gets the readings even with the term off; one that
    # only follows the advice does not (the vote they take is not free)
    regrasping = AdvisedSensor()
    regrasping.confirm_regrasps = True
    planned = TouchAdvisor(TouchAdvisorConfig(surface_points=256), regrasping, tmp_path)
    planned.on_frame(_frame(0), {}, np.eye(4), mapper)
    np.testing.assert_allclose(planned.advice.unconfirmed, lone[:1].numpy(), atol=1e-7)
    following = TouchAdvisor(TouchAdvisorConfig(surface_points=256), AdvisedSensor(), tmp_path)
    following.on_frame(_frame(0), {}, np.eye(4), mapper)
    assert len(following.advice.unconfirmed) == 0
    advisor.write()
    assert json.loads((tmp_path / SUGGESTIONS_FILE).read_text())["unconfirmed_readings"] == 1
    with pytest.raises(ValueError, match="confirm_weight"):
        TouchScoreConfig(confirm_weight=1.5)


def test_a_sim_sensor_asks_for_readings_to_confirm_only_when_it_regrasps_for_them() -> None:
    from neuralfeels_sem.sensors.sim import SimSensor

    assert SimSensor(policy="active", planner={"confirm_regrasp_after": 4}).confirm_regrasps
    assert not SimSensor(policy="active").confirm_regrasps
    assert not SimSensor(planner={"confirm_regrasp_after": 4}).confirm_regrasps  # scripted
