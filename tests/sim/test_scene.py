"""The MuJoCo scene compiles with an object, steps without warnings and agrees with HandKinematics."""

from __future__ import annotations

import numpy as np
import pytest

from neuralfeels_sem.core.geometry import look_at
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.sim.kinematics import HandKinematics
from neuralfeels_sem.sim.rig_params import NOMINAL_Q
from neuralfeels_sem.sim.scene import SimScene
from tests.sim.shapes import box, two_material_sphere


def _object_pose(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


@pytest.mark.parametrize("make", [two_material_sphere, box])
def test_scene_steps_200_steps_without_warnings(make) -> None:
    scene = SimScene(make(), world_T_camera=look_at(np.array([0.4, 0.3, 0.4]), np.zeros(3)))
    scene.set_state(NOMINAL_Q, _object_pose(-0.03, 0.0, 0.24))
    scene.step(200)
    assert scene.warning_count == 0
    # The servos hold the commanded posture and the mocap object stays where it was put.
    np.testing.assert_allclose(scene.joint_positions, NOMINAL_Q, atol=0.02)
    np.testing.assert_allclose(scene.object_pose()[:3, 3], [-0.03, 0.0, 0.24], atol=1e-12)


def test_scene_sensor_poses_match_hand_kinematics() -> None:
    scene = SimScene(two_material_sphere())
    rng = np.random.default_rng(0)
    hand = HandKinematics(scene.world_T_palm)
    limits = hand.joint_limits
    for _ in range(3):
        q = rng.uniform(limits[:, 0], limits[:, 1])
        scene.set_state(q, _object_pose(0.0, 0.0, 0.3))
        expected = hand.sensor_poses(q)
        for finger in FINGERS:
            np.testing.assert_allclose(scene.sensor_poses()[finger], expected[finger], atol=1e-9)


def test_ray_cast_hits_the_object_surface_with_its_normal() -> None:
    radius = 0.04
    scene = SimScene(two_material_sphere(radius))
    centre = np.array([0.1, -0.05, 0.3])
    scene.set_state(NOMINAL_Q, _object_pose(*centre))
    origin = centre + np.array([0.2, 0.0, 0.01])
    dist, normal = scene.ray_object(origin, np.array([-1.0, 0.0, 0.0]))
    hit = origin + dist * np.array([-1.0, 0.0, 0.0])
    # On the (tessellated) sphere: within 0.5 mm of the radius; normal points outward.
    assert np.linalg.norm(hit - centre) == pytest.approx(radius, abs=5e-4)
    assert normal @ (hit - centre) / radius > 0.99
    # The hand is not part of the object group: a ray through the palm region misses.
    miss, _ = scene.ray_object(origin + np.array([0.0, 0.0, -0.3]), np.array([-1.0, 0.0, 0.0]))
    assert miss == -1.0


def test_hand_meshes_follow_the_joint_state() -> None:
    scene = SimScene(box())
    scene.set_state(np.zeros(16), _object_pose(0.0, 0.0, 0.5))
    straight = scene.hand_meshes()
    scene.set_state(NOMINAL_Q + 0.05, _object_pose(0.0, 0.0, 0.5))  # every joint moved
    bent = scene.hand_meshes()
    assert len(straight) == len(bent) == 17  # palm + 12 links + 4 DIGIT bodies
    moved = [not np.allclose(a[1], b[1]) for a, b in zip(straight, bent)]
    assert moved[0] is False  # the palm does not move
    assert sum(moved) == 16


def test_set_state_rejects_a_bad_joint_vector() -> None:
    scene = SimScene(box())
    with pytest.raises(ValueError, match="16"):
        scene.set_state(np.zeros(12), np.eye(4))


@pytest.mark.parametrize("name", ["plushie", "candle_holder"])
def test_library_objects_load_and_step_without_warnings(name: str) -> None:
    from neuralfeels_sem.objects.library import make_object
    from neuralfeels_sem.sim.rig import SimRig

    rig = SimRig(make_object(name, list(DEFAULT_MATERIALS)))
    rig.state_at(0.0)
    rig.scene.step(200)
    assert rig.scene.warning_count == 0
