"""The rig over a 10 s run: fingers gait, touches sweep the surface, the thumb presses less."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from neuralfeels_sem.bench.finger_contacts import finger_gaps, finger_geoms, main, measure
from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.kinematics import HandKinematics
from neuralfeels_sem.sim.rig import SimRig
from neuralfeels_sem.sim.rig_params import BOTTOM_COS, OVERLAP_TOLERANCE_M
from tests.sim.shapes import CLASSES, two_material_sphere


@pytest.fixture(scope="module")
def run():
    obj = two_material_sphere(0.04)
    rig = SimRig(obj, seed=0)
    states = [rig.state_at(i / 10) for i in range(100)]
    return obj, rig, states


def test_every_finger_breaks_and_remakes_contact(run) -> None:
    _, _, states = run
    for finger in FINGERS:
        touching = np.array([s.touching[finger] for s in states])
        remakes = np.count_nonzero(~touching[:-1] & touching[1:])
        breaks = np.count_nonzero(touching[:-1] & ~touching[1:])
        assert remakes >= 4, finger  # one gait cycle per 1.2 s
        assert breaks >= 4, finger
    per_frame = np.array([sum(s.touching.values()) for s in states])
    assert per_frame[5:].min() >= 2  # after the first touch-downs, at least two fingers hold on
    assert per_frame.mean() >= 2.5


def test_touches_sweep_a_substantial_share_of_the_surface(run) -> None:
    obj, _, states = run
    touched = np.array([p for s in states for p in s.contact_point.values() if p is not None])
    samples, _, _ = obj.sample_surface(4000, seed=0)
    distance, _ = cKDTree(touched).query(samples)
    # Measured: 41% of the sphere within 1 cm of a touched point in 10 s at 30 deg/s.
    assert (distance < 0.01).mean() > 0.3
    # Touches are on the surface (object frame).
    assert np.abs(np.linalg.norm(touched, axis=1) - 0.04).max() < 1e-3


def test_press_depth_follows_firmness_and_the_thumb_presses_less(run) -> None:
    _, rig, states = run
    mean_press = {}
    for finger in FINGERS:
        press = [s.press_m[finger] for s in states if s.touching[finger]]
        mean_press[finger] = float(np.mean(press))
        assert mean_press[finger] == pytest.approx(rig.press[finger], abs=2e-4)
        assert max(press) < 0.0025  # never past the gel's travel
    assert mean_press["thumb"] < 0.6 * mean_press["index"]


def test_joint_state_is_a_valid_mujoco_state(run) -> None:
    _, rig, states = run
    limits = HandKinematics().joint_limits
    q = np.array([s.joint_positions for s in states])
    assert np.all(q >= limits[:, 0] - 1e-9) and np.all(q <= limits[:, 1] + 1e-9)
    # Sensor poses reported by the rig are the forward kinematics of its joint state.
    hand = HandKinematics(rig.scene.world_T_palm)
    for s in states[::20]:
        for finger, pose in hand.sensor_poses(s.joint_positions).items():
            np.testing.assert_allclose(pose, s.world_T_sensor[finger], atol=1e-9)
    # Touching fingers sit where the IK put them (sub-millimetre).
    errors = [s.ik_error_m[f] for s in states for f in FINGERS if s.touching[f]]
    assert np.median(errors) < 1e-3
    rig.scene.step(200)
    assert rig.scene.warning_count == 0


def test_same_seed_same_run_other_seed_other_touches(run) -> None:
    obj, _, states = run
    again = SimRig(obj, seed=0)
    np.testing.assert_allclose(again.state_at(0.0).joint_positions, states[0].joint_positions)
    np.testing.assert_allclose(again.state_at(0.1).joint_positions, states[1].joint_positions)
    other = SimRig(obj, seed=1)
    assert not np.allclose(other.state_at(0.0).joint_positions, states[0].joint_positions)


def test_unknown_finger_and_bad_firmness_are_value_errors() -> None:
    obj = two_material_sphere()
    with pytest.raises(ValueError, match="fingers"):
        SimRig(obj, fingers=["pinky"])
    with pytest.raises(ValueError, match="press depth"):
        SimRig(obj, press_depth_m={"index": 0.004, "middle": 0.001, "ring": 0.001, "thumb": 0.001})


def test_other_rotation_axis_turns_about_it_and_fingers_still_touch() -> None:
    obj = two_material_sphere(0.04)
    rig = SimRig(obj, axis=(1.0, 0.0, 0.0), wobble_deg=0.0)
    states = [rig.state_at(i / 10) for i in range(30)]
    rot = states[-1].world_T_object[:3, :3]
    np.testing.assert_allclose(rot @ np.array([1.0, 0.0, 0.0]), [1.0, 0.0, 0.0], atol=1e-9)
    angle = np.degrees(np.arccos(np.clip((np.trace(rot) - 1) / 2, -1, 1)))
    assert angle == pytest.approx(30.0 * 2.9, abs=1e-6)
    assert np.mean([sum(s.touching.values()) for s in states]) >= 2.0


def test_fingers_do_not_run_into_each_other(run) -> None:
    _, rig, states = run
    hand = HandKinematics(rig.scene.world_T_palm)
    geoms = finger_geoms(hand.model)
    worst = np.inf
    for s in states:
        hand.sensor_poses(s.joint_positions)
        worst = min(worst, *finger_gaps(hand.model, hand.data, geoms).values())
    # Links and DIGIT bodies of different fingers at most touch (run-time tolerance 1 mm).
    assert worst >= -OVERLAP_TOLERANCE_M - 1e-4


def test_an_alternate_axis_brings_the_poles_round_to_the_fingers() -> None:
    # About z alone the fingers touch a band round the sphere; turning about y in turn
    # brings its top and bottom (the poles of z) round to them.
    obj = two_material_sphere(0.04)
    polar = {}
    for name, alternate in (("one axis", None), ("alternating", (0.0, 1.0, 0.0))):
        rig = SimRig(obj, wobble_deg=0.0, alternate_axis=alternate, alternate_every_s=1.5)
        states = [rig.state_at(i / 10) for i in range(60)]
        assert np.mean([sum(s.touching.values()) for s in states[10:]]) >= 2.0, name
        points = np.array([p for s in states for p in s.contact_point.values() if p is not None])
        latitude = np.degrees(np.arcsin(np.abs(points[:, 2]) / np.linalg.norm(points, axis=1)))
        polar[name] = np.percentile(latitude, 90)
    assert polar["alternating"] > polar["one axis"] + 15.0, polar


def test_fingers_keep_off_a_flat_base_that_the_alternate_axis_brings_round() -> None:
    from neuralfeels_sem.sim.rig_params import flat_base_share

    mesh = trimesh.creation.cylinder(radius=0.03, height=0.06, sections=48)
    obj = MaterialObject("can", mesh, np.zeros(len(mesh.faces), int), CLASSES)
    assert flat_base_share(obj.mesh) == pytest.approx(1 / 6, abs=0.01)  # r / (2r + 2h)
    assert flat_base_share(two_material_sphere(0.04).mesh) < 0.02  # no flat base: no rule
    rig = SimRig(obj, alternate_axis=(0.0, 1.0, 0.0), alternate_every_s=1.5)
    normals = []
    for i in range(60):
        state = rig.state_at(i / 10)
        for finger, point in state.contact_point.items():
            if point is not None:
                normals.append(
                    rig.policy.last_contact[
                        (finger, rig.policy.cycle_and_phase(finger, i / 10)[0])
                    ].normal
                )
    normals = np.array(normals)
    assert len(normals) > 60
    assert (normals[:, 2] < -BOTTOM_COS).sum() == 0  # never held on the base
    assert (normals[:, 2] > BOTTOM_COS).sum() > 0  # while the top does come round


def test_no_finger_ends_a_step_inside_the_object() -> None:
    """Generated object 103 at seed 1, the default motion: without SimRig._back_out the index
    finger ended frame 17 with the object 19 mm into its gel (a frame of a default 30 s run)."""
    report = measure(
        "random:103", 2.0, seed=1, render=False, rig_options=SimSensorConfig().rig_motion()
    )
    assert report.deepest_press_mm["middle"] > 1.0  # the rig pressed: the check can see
    assert not any(report.inside_frames.values()), report.inside_frames


@pytest.mark.parametrize("name", ["random:x", "no_such_object"])
def test_finger_contacts_refuses_an_unknown_object_in_one_line(name: str, capsys) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["--objects", name, "--no-render"])
    assert stopped.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.endswith("a seed >= 0" if name.startswith("random:") else "or object=custom")
