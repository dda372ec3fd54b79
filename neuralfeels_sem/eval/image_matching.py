"""The paper's image form of the matching percentage (figure 5B).

The ground-truth mesh is rendered from fixed views; every object pixel is back-projected
to the ground-truth surface point it sees, which gives its ground-truth label (the face
it lies on) and the point at which the predictor is asked. Both maps therefore compare
exactly the same surface points, and pixels are counted inside the regions of interest.
"""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.geometry import Intrinsics, backproject, transform_points
from neuralfeels_sem.core.materials import BACKGROUND
from neuralfeels_sem.eval.matching import Predictor, predict_labels
from neuralfeels_sem.eval.mesh_render import DepthRenderer, orbit_views
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject
from neuralfeels_sem.objects.proximity import closest_surface_points

FOV_Y_DEG = 40.0


class ImageMatcher:
    """Ground-truth label maps from fixed views, computed once on first use; `maps(predict)` per call."""

    def __init__(
        self,
        obj: MaterialObject,
        views: int = 4,
        size: int = 256,
        elevation_deg: float = 30.0,
        seed: int = 0,
    ) -> None:
        if views < 1 or size < 8:
            raise ValueError(f"ImageMatcher needs views >= 1 and size >= 8, got {views}, {size}")
        self.obj = obj
        self.num_views = views
        self.size = size
        self.elevation_deg = elevation_deg
        # Seed 0 starts at azimuth 0; other seeds turn the whole ring of views by a fixed random angle.
        self.azimuth_offset_deg = (
            0.0 if seed == 0 else float(np.random.default_rng(seed).uniform(0, 360 / views))
        )
        self.intrinsics = Intrinsics.from_fov(size, size, FOV_Y_DEG)
        self._ready = False

    def _prepare(self) -> None:
        if not (self.obj.face_labels != IGNORE).any():
            raise NoDataError(
                f"object {self.obj.name!r} has no region of interest (every face label is ignore); "
                "matching percentage cannot be computed: label some faces with a material"
            )
        mesh = self.obj.mesh
        center = mesh.bounds.mean(axis=0)
        radius = float(np.linalg.norm(mesh.vertices - center, axis=1).max())
        self.poses = orbit_views(
            center, radius, self.num_views, self.elevation_deg, FOV_Y_DEG, self.azimuth_offset_deg
        )
        shape = (self.num_views, self.size, self.size)
        self.gt = np.full(shape, BACKGROUND, dtype=np.int64)
        self.depth = np.zeros(shape, dtype=np.float32)
        self.shade = np.ones(shape, dtype=np.float32)
        self._pixels: list[np.ndarray] = []  # flat pixel indices of object pixels, per view
        points = []
        with DepthRenderer(mesh, self.intrinsics) as renderer:
            for v, object_T_camera in enumerate(self.poses):
                depth = renderer.render(object_T_camera)
                self.depth[v] = depth
                visible = depth > 0
                seen = transform_points(
                    object_T_camera, backproject(depth, self.intrinsics, visible)
                )
                # Snap to the surface (depth-buffer error is ~0.1 mm), so the point the predictor
                # is asked at lies on the face that gives the pixel its ground-truth label.
                faces, _, pts = closest_surface_points(mesh, seen)
                self._pixels.append(np.flatnonzero(visible))
                self.gt[v][visible] = self.obj.face_labels[faces]
                # Lambert-like shading from the face normal, only for pictures.
                to_camera = object_T_camera[:3, 3] - seen
                to_camera /= np.linalg.norm(to_camera, axis=1, keepdims=True)
                cos = np.abs(np.sum(mesh.face_normals[faces] * to_camera, axis=1))
                self.shade[v][visible] = 0.45 + 0.55 * cos
                points.append(pts)
        self.points = np.concatenate(points) if points else np.zeros((0, 3))
        self._ready = True

    def maps(self, predict: Predictor) -> dict:
        """{'gt', 'pred', 'diff', 'shade', 'matching_pct_image', 'poses', 'intrinsics'} for a predictor.

        gt, pred: (V, H, W) int64 labels (IGNORE = -1 on gt only, BACKGROUND = -2);
        diff: (V, H, W) bool, True where gt is in the regions of interest and pred differs.
        matching_pct_image is NaN when no region-of-interest pixel is visible from the views
        (e.g. a region only on the underside); the 3D form still scores it.
        """
        points = self.surface_points()
        labels = predict_labels(predict, points) if len(points) else np.zeros(0, dtype=np.int64)
        return self.label_maps(labels)

    def surface_points(self) -> np.ndarray:
        """(P, 3) ground-truth surface points the object pixels see, views in order."""
        if not self._ready:
            self._prepare()
        return self.points

    def value_image(self, values: np.ndarray) -> np.ndarray:
        """(P,) values at `surface_points()` -> (V, H, W) float32 images, NaN off the object."""
        points = self.surface_points()
        values = np.asarray(values, dtype=np.float32)
        if values.shape != (len(points),):
            raise ValueError(f"{values.shape} values for {len(points)} surface points")
        image = np.full(self.gt.shape, np.nan, dtype=np.float32)
        start = 0
        for v, pixels in enumerate(self._pixels):
            image[v].reshape(-1)[pixels] = values[start : start + len(pixels)]
            start += len(pixels)
        return image

    def label_maps(self, labels: np.ndarray) -> dict:
        """`maps` of classes already predicted at `surface_points()`."""
        if not self._ready:
            self._prepare()
        if labels.shape != (len(self.points),):
            raise ValueError(f"{labels.shape} labels for {len(self.points)} surface points")
        pred = np.full_like(self.gt, BACKGROUND)
        start = 0
        for v, pixels in enumerate(self._pixels):
            pred[v].reshape(-1)[pixels] = labels[start : start + len(pixels)]
            start += len(pixels)
        roi = self.gt >= 0
        diff = roi & (pred != self.gt)
        pct = float(100.0 * (1.0 - diff.sum() / roi.sum())) if roi.any() else float("nan")
        return {
            "gt": self.gt.copy(),
            "pred": pred,
            "diff": diff,
            "shade": self.shade.copy(),
            "matching_pct_image": pct,
            "poses": [p.copy() for p in self.poses],
            "intrinsics": self.intrinsics.to_dict(),
        }


def render_label_maps(
    obj: MaterialObject,
    predict: Predictor,
    views: int = 4,
    size: int = 256,
    seed: int = 0,
    elevation_deg: float = 30.0,
) -> dict:
    """One-off image-form evaluation; see ImageMatcher.maps for the keys.

    For repeated evaluation over a run, keep one ImageMatcher: it renders the ground truth once.
    """
    return ImageMatcher(obj, views, size, elevation_deg, seed).maps(predict)
