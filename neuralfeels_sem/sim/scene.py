"""The MuJoCo scene: table, hand with four DIGITs, the object on a mocap body, the camera.

The object is driven kinematically (a mocap body following the manipulation policy's
trajectory) and hand-object collision is disabled: fingers are placed by IK and the
tactile contact is rendered from geometry, so the constraint solver never fights a
prescribed motion. The object mesh is still part of the model, for ray casting (where
fingers touch) and for MuJoCo's own viewers.
"""

from __future__ import annotations

import io

import mujoco
import numpy as np
import trimesh

from neuralfeels_sem.core.geometry import OPENGL_T_OPENCV, check_pose
from neuralfeels_sem.core.hand import FINGERS, default_world_T_palm
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.hand_model import hand_actuators_xml, hand_body_xml, hand_defaults_xml
from neuralfeels_sem.sim.kinematics import geom_pose, geom_trimesh, site_pose

OBJECT_GROUP = 2  # geom group of the object (ray casts see only this group)


def _fmt(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.ravel(values))


def _quat(rot: np.ndarray) -> np.ndarray:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rot, dtype=np.float64).ravel())
    return quat


def scene_xml(world_T_palm: np.ndarray, world_T_camera: np.ndarray, timestep: float) -> str:
    # MuJoCo cameras look along -z (OpenGL); ours are OpenCV, converted here at the boundary.
    cam_rot = world_T_camera[:3, :3] @ OPENGL_T_OPENCV[:3, :3]
    return (
        '<mujoco model="semanticfeels_rig"><compiler angle="radian" autolimits="true"/>'
        f'<option timestep="{timestep}" gravity="0 0 -9.81"/>'
        '<visual><global offwidth="640" offheight="480"/></visual>'
        '<asset><mesh name="object_mesh" file="object.stl" inertia="shell"/></asset>'
        f"<default>{hand_defaults_xml()}</default>"
        "<worldbody>"
        '<light pos="0 0 1.5" dir="0 0 -1" directional="true"/>'
        '<geom name="table" type="plane" size="0.5 0.5 0.01" rgba="0.55 0.45 0.35 1"/>'
        f'<camera name="front_left" pos="{_fmt(world_T_camera[:3, 3])}" quat="{_fmt(_quat(cam_rot))}" fovy="50"/>'
        f"{hand_body_xml(world_T_palm)}"
        '<body name="object" mocap="true">'
        f'<geom name="object" type="mesh" mesh="object_mesh" contype="0" conaffinity="0" group="{OBJECT_GROUP}" '
        'rgba="0.8 0.6 0.4 1"/></body>'
        "</worldbody>"
        f"<actuator>{hand_actuators_xml()}</actuator></mujoco>"
    )


class SimScene:
    """A compiled rig for one object. Construction compiles the model (tens of ms)."""

    def __init__(
        self,
        obj: MaterialObject,
        world_T_palm: np.ndarray | None = None,
        world_T_camera: np.ndarray | None = None,
        timestep: float = 0.002,
    ) -> None:
        self.obj = obj
        self.world_T_palm = (
            default_world_T_palm() if world_T_palm is None else np.asarray(world_T_palm, float)
        )
        self.world_T_camera = (
            np.eye(4) if world_T_camera is None else np.asarray(world_T_camera, float)
        )
        check_pose(self.world_T_palm, "world_T_palm")
        check_pose(self.world_T_camera, "world_T_camera")
        stl = io.BytesIO()
        obj.mesh.export(stl, file_type="stl")
        xml = scene_xml(self.world_T_palm, self.world_T_camera, timestep)
        self.model = mujoco.MjModel.from_xml_string(xml, assets={"object.stl": stl.getvalue()})
        self.data = mujoco.MjData(self.model)
        self.object_geom = self.model.geom("object").id
        self.object_body = self.model.body("object").id
        self._mocap = self.model.body_mocapid[self.object_body]
        self._sensor_sites = {f: self.model.site(f"{f}_digit").id for f in FINGERS}
        self.object_groups = np.zeros(6, np.uint8)  # ray casts see only the object
        self.object_groups[OBJECT_GROUP] = 1
        self._hand_meshes: list[tuple[int, trimesh.Trimesh]] | None = None
        mujoco.mj_forward(self.model, self.data)

    # ------------------------------------------------------------------ state
    def set_state(self, q: np.ndarray, world_T_object: np.ndarray) -> None:
        """Write the hand joints (qpos and servo targets) and the object pose, then mj_forward."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (16,):
            raise ValueError(f"joint positions must have shape (16,), got {q.shape}")
        self.data.qpos[:] = q
        self.data.qvel[:] = 0.0
        self.data.ctrl[:] = q
        self.set_object_pose(world_T_object, self.data)
        mujoco.mj_forward(self.model, self.data)

    def set_object_pose(self, world_T_object: np.ndarray, data: mujoco.MjData) -> None:
        """Write the object's mocap pose into `data` (no forward pass)."""
        check_pose(world_T_object, "world_T_object")
        data.mocap_pos[self._mocap] = world_T_object[:3, 3]
        data.mocap_quat[self._mocap] = _quat(world_T_object[:3, :3])

    def step(self, n: int = 1) -> None:
        """Advance physics n steps (the servos hold the commanded posture)."""
        for _ in range(n):
            mujoco.mj_step(self.model, self.data)

    @property
    def warning_count(self) -> int:
        """Total MuJoCo warnings raised since the data was created (0 for a healthy scene)."""
        return int(np.sum(self.data.warning.number))

    @property
    def joint_positions(self) -> np.ndarray:
        return self.data.qpos[:16].copy()

    def object_pose(self) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3] = self.data.xmat[self.object_body].reshape(3, 3)
        pose[:3, 3] = self.data.xpos[self.object_body]
        return pose

    def hand_meshes(self) -> list[tuple[trimesh.Trimesh, np.ndarray]]:
        """Palm, links and DIGIT bodies as (mesh in its own frame, world_T_mesh), for occlusion."""
        if self._hand_meshes is None:
            hand = [g for g in range(self.model.ngeom) if self.model.geom_group[g] == 1]
            self._hand_meshes = [(g, geom_trimesh(self.model, g)) for g in hand]
        return [(mesh, geom_pose(self.data, g)) for g, mesh in self._hand_meshes]

    def sensor_poses(self) -> dict[str, np.ndarray]:
        """finger -> world_T_sensor of its DIGIT in the current state."""
        return {f: site_pose(self.data, sid) for f, sid in self._sensor_sites.items()}

    # ------------------------------------------------------------------ geometry queries
    def ray_object(
        self, origin: np.ndarray, direction: np.ndarray, data: mujoco.MjData | None = None
    ) -> tuple[float, np.ndarray]:
        """Distance along a unit `direction` to the object surface (-1 = miss) and its normal there.

        `data` defaults to the scene's state; pass another MjData of this model to probe
        other object poses.
        """
        geomid = np.zeros(1, np.int32)
        normal = np.zeros(3)
        dist = mujoco.mj_ray(
            self.model,
            self.data if data is None else data,
            np.asarray(origin, np.float64),
            np.asarray(direction, np.float64),
            self.object_groups,
            1,
            -1,
            geomid,
            normal,
        )
        return float(dist), normal
