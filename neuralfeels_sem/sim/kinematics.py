"""Forward kinematics of the simulated hand, usable without a scene (e.g. by the real Allegro driver)."""

from __future__ import annotations

import mujoco
import numpy as np
import trimesh

from neuralfeels_sem.core.geometry import check_pose
from neuralfeels_sem.core.hand import FINGERS, default_world_T_palm
from neuralfeels_sem.sim.hand_model import hand_only_xml, joint_specs


def site_pose(data: mujoco.MjData, site_id: int) -> np.ndarray:
    """world_T_site of a MuJoCo site as a 4x4 matrix."""
    pose = np.eye(4)
    pose[:3, :3] = data.site_xmat[site_id].reshape(3, 3)
    pose[:3, 3] = data.site_xpos[site_id]
    return pose


def geom_pose(data: mujoco.MjData, geom_id: int) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = data.geom_xmat[geom_id].reshape(3, 3)
    pose[:3, 3] = data.geom_xpos[geom_id]
    return pose


def geom_trimesh(model: mujoco.MjModel, geom_id: int) -> trimesh.Trimesh:
    """Triangle mesh of a capsule or box geom in its own frame (for occlusion rendering)."""
    size = model.geom_size[geom_id]
    kind = model.geom_type[geom_id]
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[12, 12])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return trimesh.creation.box(extents=2 * size[:3])
    raise ValueError(f"geom {model.geom(geom_id).name!r} has unsupported type {kind}")


class HandKinematics:
    """16-joint hand (index 0-3, middle 4-7, ring 8-11, thumb 12-15) with a DIGIT per fingertip.

    `sensor_poses(q)` gives each DIGIT's world_T_sensor (OpenCV camera frame, gel at
    z = 20 mm). The MuJoCo model is compiled on first use, so construction is free.
    """

    def __init__(self, world_T_palm: np.ndarray | None = None) -> None:
        self.world_T_palm = (
            default_world_T_palm() if world_T_palm is None else np.asarray(world_T_palm, float)
        )
        check_pose(self.world_T_palm, "world_T_palm")
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self._meshes: list[tuple[int, trimesh.Trimesh]] | None = None

    @property
    def joint_names(self) -> list[str]:
        return [s.name for s in joint_specs()]

    @property
    def joint_limits(self) -> np.ndarray:
        """(16, 2) lower and upper limit of each joint, radians."""
        return np.array([(s.lower, s.upper) for s in joint_specs()])

    @property
    def model(self) -> mujoco.MjModel:
        if self._model is None:
            self._model = mujoco.MjModel.from_xml_string(hand_only_xml(self.world_T_palm))
            self._data = mujoco.MjData(self._model)
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        _ = self.model
        return self._data

    def clip(self, q: np.ndarray) -> np.ndarray:
        limits = self.joint_limits
        return np.clip(q, limits[:, 0], limits[:, 1])

    def _forward(self, q: np.ndarray) -> mujoco.MjData:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (16,):
            raise ValueError(f"joint positions must have shape (16,), got {q.shape}")
        model, data = self.model, self.data
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        return data

    def sensor_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """finger -> world_T_sensor (4x4) of its DIGIT for joint positions q (16,)."""
        data = self._forward(q)
        return {f: site_pose(data, self.model.site(f"{f}_digit").id) for f in FINGERS}

    def gel_centres(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """finger -> world position (3,) of the centre of its gel's outer surface."""
        data = self._forward(q)
        return {f: data.site_xpos[self.model.site(f"{f}_gel").id].copy() for f in FINGERS}

    def link_meshes(self, q: np.ndarray) -> list[tuple[trimesh.Trimesh, np.ndarray]]:
        """Every palm, link and DIGIT body as (mesh in its own frame, world_T_mesh)."""
        data = self._forward(q)
        if self._meshes is None:
            self._meshes = [(g, geom_trimesh(self.model, g)) for g in range(self.model.ngeom)]
        return [(mesh, geom_pose(data, g)) for g, mesh in self._meshes]
