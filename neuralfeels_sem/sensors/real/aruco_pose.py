"""Object pose from ArUco markers fixed on the object, seen by the RGB-D camera (opencv-contrib).

Each marker's pose on the object (`object_T_marker`, [x, y, z, rx, ry, rz]) comes from
the object's config (`object.aruco`); the detection settings come from `sensor.object_pose`.
All detected markers' corners go into one PnP solve, so two or more markers give a
well-conditioned pose. Marker frame as OpenCV defines it: centre origin, x right, y up,
z out of the marker; corners in detector order top-left, top-right, bottom-right, bottom-left.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.core.geometry import Intrinsics, transform_points
from neuralfeels_sem.sensors.real.poses import pose_from_vector


def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"unknown ArUco dictionary {name!r} (e.g. DICT_4X4_50)")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def marker_corners(length_m: float) -> np.ndarray:
    """(4, 3) corners of a square marker in its own frame, detector order."""
    h = length_m / 2.0
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def detect_markers(rgb: np.ndarray, dictionary: cv2.aruco.Dictionary) -> dict[int, np.ndarray]:
    """Marker id -> (4, 2) pixel corners found in an RGB image."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = (
        cv2.aruco.CORNER_REFINE_SUBPIX
    )  # sub-pixel corners: mm-level poses
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary, params).detectMarkers(gray)
    if ids is None:
        return {}
    return {int(i): c.reshape(4, 2).astype(np.float64) for i, c in zip(ids.ravel(), corners)}


def solve_pnp(
    object_points: np.ndarray, image_points: np.ndarray, intrinsics: Intrinsics
) -> tuple[np.ndarray, float]:
    """camera_T_frame from 3D-2D correspondences (no distortion); returns (4x4, RMS reprojection px)."""
    if len(object_points) < 4 or object_points.shape[0] != image_points.shape[0]:
        raise ValueError(
            f"PnP needs >= 4 matched points, got {object_points.shape} / {image_points.shape}"
        )
    ok, rvec, tvec = cv2.solvePnP(
        object_points,
        image_points,
        intrinsics.matrix,
        None,
        flags=cv2.SOLVEPNP_IPPE if len(object_points) == 4 else cv2.SOLVEPNP_ITERATIVE,
    )
    if not ok:
        raise ValueError("PnP failed")
    pose = np.eye(4)
    pose[:3, :3] = cv2.Rodrigues(rvec)[0]
    pose[:3, 3] = tvec.ravel()
    projected, _ = cv2.projectPoints(object_points, rvec, tvec, intrinsics.matrix, None)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - image_points) ** 2, axis=1))))
    return pose, rms


class ArucoObjectPose:
    """world_T_object from the markers visible in one camera image."""

    def __init__(
        self,
        markers: Mapping[int | str, Sequence[float]],
        marker_length_m: float = 0.02,
        dictionary: str = "DICT_4X4_50",
        max_reprojection_px: float = 3.0,
    ) -> None:
        if marker_length_m <= 0:
            raise ValueError(f"marker_length_m={marker_length_m} must be > 0")
        # Empty: the object has no layout; RealSensor.open() reports it (MISSING_LAYOUT).
        self.object_T_marker = {int(k): pose_from_vector(v) for k, v in markers.items()}
        self.marker_length_m = marker_length_m
        self.dictionary_name = dictionary
        self.max_reprojection_px = max_reprojection_px
        self._dictionary = None

    def estimate(
        self, rgb: np.ndarray, intrinsics: Intrinsics, world_T_camera: np.ndarray
    ) -> np.ndarray | None:
        """world_T_object, or None when no configured marker is seen or the fit is poor."""
        if self._dictionary is None:
            self._dictionary = aruco_dictionary(self.dictionary_name)
        found = detect_markers(rgb, self._dictionary)
        ids = [i for i in found if i in self.object_T_marker]
        if not ids:
            return None
        corners = marker_corners(self.marker_length_m)
        object_points = np.concatenate(
            [transform_points(self.object_T_marker[i], corners) for i in ids]
        )
        image_points = np.concatenate([found[i] for i in ids])
        camera_T_object, rms = solve_pnp(object_points, image_points, intrinsics)
        if rms > self.max_reprojection_px:
            return None
        return world_T_camera @ camera_T_object


MISSING_LAYOUT = (
    "the object pose comes from ArUco markers but the object has no marker layout: set "
    "object.aruco.markers (e.g. [{id: 3, pose: [x, y, z, rx, ry, rz]}], object_T_marker) and "
    "object.aruco.marker_length_m in the object's config, or sensor.object_pose=null to keep "
    "sensor.world_T_object (e.g. with mapping.pose=track)"
)


def from_object_layout(
    layout: Mapping | None,
    dictionary: str = "DICT_4X4_50",
    max_reprojection_px: float = 3.0,
) -> ArucoObjectPose:
    """The estimator for sensor.object_pose: detection settings from the sensor, markers from the object.

    `layout` is the object's `aruco` entry ({marker_length_m, markers: [{id, pose}]}), wired
    in by conf/sensor/real.yaml. Without markers the estimator is still built (every config
    instantiates); RealSensor.open() then stops the run with MISSING_LAYOUT.
    """
    layout = layout or {}
    try:
        aruco_dictionary(dictionary)
    except ValueError as exc:
        raise ConfigError(f"sensor.object_pose.dictionary: {exc}") from exc
    markers = {int(m["id"]): m["pose"] for m in layout.get("markers") or []}
    return ArucoObjectPose(
        markers,
        marker_length_m=float(layout.get("marker_length_m", 0.02)),
        dictionary=dictionary,
        max_reprojection_px=max_reprojection_px,
    )
