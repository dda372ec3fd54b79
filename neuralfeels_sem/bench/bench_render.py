"""Rendering speed of the simulated rig: 4 DIGITs + 1 RGB-D camera per frame.

Object: a 2-material icosphere of 3 cm radius (20k faces, like the shipped objects). Fingers press at
different places (0.4-1.0 mm: typical patches of a grasp); extra cases: 2 mm from the
surface (no contact, GL pass still runs) and 2 cm away (culled, no GL pass).
Target: the whole rig at >= 10 Hz on 2 CPU cores (tactile <= ~12 ms, camera <= ~20 ms).
"""

from __future__ import annotations

import os
import time

import numpy as np
import trimesh

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.camera_renderer import CameraRenderer, front_left_camera_pose
from neuralfeels_sem.sim.digit_poses import pose_pressing
from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

REPEATS = 30


def _object() -> MaterialObject:
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=0.03)
    labels = (mesh.triangles_center[:, 0] > 0).astype(int) * 2  # plastic | fabric
    return MaterialObject("bench_sphere", mesh, labels, tuple(DEFAULT_MATERIALS))


def _ms(fn, repeats: int = REPEATS) -> tuple[float, float]:
    """(wall ms, CPU ms of this process) per call.

    CPU time counts this process's threads only (numpy + llvmpipe), so on a machine shared
    with other jobs it is the better estimate of what a quiet machine would take.
    """
    fn()  # warm-up: GL context, VBO upload
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(repeats):
        fn()
    return 1e3 * (time.perf_counter() - wall) / repeats, 1e3 * (time.process_time() - cpu) / repeats


def run() -> dict:
    obj = _object()
    world_T_object = np.eye(4)
    world_T_object[:3, 3] = (0.0, 0.0, 0.15)
    directions = np.array([[1.0, 0.2, 0.3], [-0.8, 0.4, 0.2], [0.1, 1.0, -0.2], [0.3, -1.0, 0.1]])
    presses = (0.4e-3, 0.6e-3, 0.8e-3, 1.0e-3)
    sensor_poses = []
    for direction, press in zip(directions, presses):
        n = direction / np.linalg.norm(direction)
        sensor_poses.append(pose_pressing(world_T_object[:3, 3] + 0.03 * n, n, press))
    fingers = [DigitRenderer(obj, seed=i) for i in range(4)]
    camera = CameraRenderer(obj, world_T_camera=front_left_camera_pose(world_T_object[:3, 3]))
    finger_link = trimesh.creation.capsule(height=0.04, radius=0.01)
    link_pose = np.eye(4)
    link_pose[:3, 3] = world_T_object[:3, 3] + np.array([0.05, 0.05, 0.02])

    contact_px = [
        int(f.render(world_T_object, p).contact_mask.sum()) for f, p in zip(fingers, sensor_poses)
    ]
    away = pose_pressing(
        world_T_object[:3, 3] + np.array([0.0, 0.0, 0.03]), np.array([0.0, 0.0, 1.0]), -2e-3
    )
    contact_wall, contact_cpu = _ms(
        lambda: [f.render(world_T_object, p) for f, p in zip(fingers, sensor_poses)]
    )
    free_wall, free_cpu = _ms(lambda: fingers[0].render(world_T_object, away))
    lifted = pose_pressing(
        world_T_object[:3, 3] + np.array([0.0, 0.0, 0.03]), np.array([0.0, 0.0, 1.0]), -2e-2
    )
    lifted_wall, lifted_cpu = _ms(lambda: fingers[0].render(world_T_object, lifted))
    camera_wall, camera_cpu = _ms(
        lambda: camera.render(world_T_object, occluders=[(finger_link, link_pose)])
    )

    def rig() -> None:
        for f, p in zip(fingers, sensor_poses):
            f.render(world_T_object, p)
        camera.render(world_T_object, occluders=[(finger_link, link_pose)])

    rig_wall, rig_cpu = _ms(rig, repeats=15)
    for f in fingers:
        f.close()
    camera.close()
    return {
        "tactile_ms_in_contact": round(contact_wall / 4, 2),
        "tactile_cpu_ms_in_contact": round(contact_cpu / 4, 2),
        "tactile_ms_no_contact": round(free_wall, 2),
        "tactile_cpu_ms_no_contact": round(free_cpu, 2),
        "tactile_ms_lifted_2cm": round(lifted_wall, 2),
        "tactile_cpu_ms_lifted_2cm": round(lifted_cpu, 2),
        "camera_ms": round(camera_wall, 2),
        "camera_cpu_ms": round(camera_cpu, 2),
        "rig_ms": round(rig_wall, 2),
        "rig_cpu_ms": round(rig_cpu, 2),
        "rig_hz": round(1e3 / rig_wall, 1),
        "rig_hz_from_cpu_time": round(1e3 / rig_cpu, 1),
        "contact_pixels_per_finger": contact_px,
        "object_faces": len(obj.mesh.faces),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
