"""Measurements on the rig's MuJoCo scene: gel rays (reach, press depth, touch point), finger gaps.

A mixin of SimRig: it reads `scene`, `_sensor_sites`, `_ray_geoms`, `_ray_dist`,
`_finger_geoms` and `flat_base`, which SimRig.open sets.
"""

from __future__ import annotations

import mujoco
import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M, GEL_HEIGHT_M, GEL_WIDTH_M
from neuralfeels_sem.sim.rig_params import BOTTOM_COS

GEL_GRID = np.stack(
    np.meshgrid(
        np.linspace(-0.45, 0.45, 5) * GEL_WIDTH_M, np.linspace(-0.45, 0.45, 5) * GEL_HEIGHT_M
    ),
    -1,
).reshape(-1, 2)
PROBE_BACK_M = 0.01  # reach reported when nothing is in view (m behind the gel surface)
# Unit rays from the DIGIT camera through the grid points on the gel (sensor frame).
GEL_GRID_RAYS = np.column_stack([GEL_GRID, np.full(len(GEL_GRID), GEL_DISTANCE_M)])
GEL_GRID_RAYS /= np.linalg.norm(GEL_GRID_RAYS, axis=1, keepdims=True)
CENTRE_FIRST = np.argsort(np.linalg.norm(GEL_GRID, axis=1), kind="stable")  # rays, inner first


def _gel_site(model: mujoco.MjModel, finger: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{finger}_gel")


class RigProbes:
    """Ray casts from the DIGITs' cameras and distances between fingers."""

    @staticmethod
    def _gel(
        model: mujoco.MjModel, data: mujoco.MjData, finger: str
    ) -> tuple[np.ndarray, np.ndarray]:
        sid = _gel_site(model, finger)
        return data.site_xpos[sid].copy(), data.site_xmat[sid].reshape(3, 3)[:, 2].copy()

    def _on_flat_base(self, normal: np.ndarray, world_T_object: np.ndarray) -> bool:
        """Does a world-frame surface normal face the object's own -z (its flat base)?"""
        return self.flat_base and float(normal @ -world_T_object[:3, 2]) > BOTTOM_COS

    def _gap(self, data: mujoco.MjData, a: str, b: str, upto: float = 0.01) -> float:
        """Smallest signed distance between two fingers' links and DIGIT bodies (m, up to `upto`)."""
        gap = upto
        for ga in self._finger_geoms[a]:
            for gb in self._finger_geoms[b]:
                gap = min(gap, mujoco.mj_geomDistance(self.scene.model, data, ga, gb, upto, None))
        return gap

    def _reach(
        self,
        finger: str,
        data: mujoco.MjData | None = None,
        normals: bool = False,
        points: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Per gel ray: reach of the object past the gel surface (m; -inf = miss), hit point, normal.

        Rays from the DIGIT's camera through a 5 x 5 grid on the gel, the renderer's own
        definition of depth (along the sensor's +z); hits within 10 cm. Hit points are in
        the world frame (None unless `points`); normals (outward, world) only when asked
        for, else None.
        """
        data = self.scene.data if data is None else data
        sid = self._sensor_sites[finger]
        rot = data.site_xmat[sid].reshape(3, 3)
        origin = data.site_xpos[sid].copy()
        directions = GEL_GRID_RAYS @ rot.T
        mujoco.mj_multiRay(
            self.scene.model,
            data,
            origin,
            np.ascontiguousarray(directions.ravel()),
            self.scene.object_groups,
            1,
            -1,
            self._ray_geoms,
            self._ray_dist,
            None,
            len(GEL_GRID_RAYS),
            0.1,
        )
        hit = self._ray_dist >= 0
        reach = np.where(hit, GEL_DISTANCE_M - self._ray_dist * GEL_GRID_RAYS[:, 2], -np.inf)
        if not points:
            return reach, None, None
        points = origin + self._ray_dist[:, None] * directions
        found = None
        if normals:
            found = np.zeros((len(GEL_GRID_RAYS), 3))
            for k in np.flatnonzero(hit):
                found[k] = self.scene.ray_object(origin, directions[k], data)[1]
        return reach, points, found

    def press_depth(self, finger: str) -> float:
        """Deepest reach of the object past the gel surface over the gel area (m; <= 0 = gap).

        Returns -PROBE_BACK_M when nothing is in view within 10 cm.
        """
        deepest = float(self._reach(finger, points=False)[0].max())
        return deepest if np.isfinite(deepest) else -PROBE_BACK_M

    def _touch_point(self, finger: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Surface point (world) the gel touches nearest its centre, and the normal there."""
        reach, points, _ = self._reach(finger)
        for k in CENTRE_FIRST:
            if reach[k] > 0:
                sid = self._sensor_sites[finger]
                origin = self.scene.data.site_xpos[sid]
                direction = points[k] - origin
                normal = self.scene.ray_object(origin, direction / np.linalg.norm(direction))[1]
                return points[k], normal
        return None
