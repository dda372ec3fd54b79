"""Live view of a mapping run in rerun (`viz.live=rerun`): an observer of the mapping session.

Streams, on the timelines `frame` and `sensor_time`:
- `world/camera/points`: the camera's depth back-projected to the world (every valid
  pixel, strided down to `camera_points`), coloured by its RGB;
- `world/object`: the object pose (world_T_object, the pose the frame was mapped at), and
  beneath it, in the object frame: `touches` (every classified touch so far, at its gel
  centre, coloured and named by predicted material, core/palette.py), `map` (the field's
  mesh coloured by material at each scoring pass) and `map_uncertainty` (the same mesh
  coloured by the material branch's normalised entropy, 0 dark to 1 bright);
- `world/hand/<finger>`: each DIGIT's pose, with its gel centre at `world/hand/gel_centres`;
- `scores/<figure>`: the matching figures of each scoring pass.
Everything goes to `live.rrd` in the run directory (`rerun live.rrd` opens it later); with
`spawn` and a display ($DISPLAY or $WAYLAND_DISPLAY) a viewer is started too and shows the
run as it happens (without a display: a warning, and the file only). rerun-sdk is an optional
extra (`pip install -e .[live]`): tasks/preflight.py refuses `viz.live=rerun` without it.
Observers only read the mapper, so a run maps the same with and without this view.
"""

from __future__ import annotations

import importlib
import logging
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import backproject, invert_pose, transform_points
from neuralfeels_sem.core.palette import class_colours
from neuralfeels_sem.mapping.mesh import extract_mesh
from neuralfeels_sem.perception.touch import NO_LABEL, TouchLabel

log = logging.getLogger(__name__)

LIVE_VIEWERS = ("none", "rerun")
RRD_NAME = "live.rrd"
INSTALL_HINT = "pip install -e .[live] (or pip install rerun-sdk)"
# Scores streamed as time series (metrics.json keys; docs/evaluation.md defines them).
STREAMED_SCORES = ("matching_mean_class_pct", "matching_pct", "fscore_5mm")


def rerun_import_error() -> str | None:
    """Why rerun-sdk cannot be imported here, or None when it can."""
    try:
        importlib.import_module("rerun")
    except ImportError as exc:
        return str(exc) or type(exc).__name__
    return None


def has_display() -> bool:
    """Whether a viewer window could open here."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def build_live_view(
    kind: str, out_dir: Path, class_names: Sequence[str], **settings
) -> list[RerunLiveView]:
    """The session observers for `viz.live=kind`: none, or a RerunLiveView (`settings`)."""
    if kind not in LIVE_VIEWERS:
        raise ValueError(f"live view {kind!r}: use one of {LIVE_VIEWERS}")
    return [] if kind == "none" else [RerunLiveView(out_dir, class_names, **settings)]


class RerunLiveView:
    """A FrameObserver (pipeline/observers.py) logging the run to a rerun recording."""

    def __init__(
        self,
        out_dir: Path,
        class_names: Sequence[str],
        spawn: bool = False,
        mesh_resolution: int = 64,
        camera_points: int = 10000,
    ) -> None:
        import rerun as rr  # the optional extra: imported only when the view is asked for

        self.rr = rr
        self.path = Path(out_dir) / RRD_NAME
        self.class_names = list(class_names)
        self.mesh_resolution = mesh_resolution
        self.camera_points = camera_points
        self.touches: list[tuple[np.ndarray, int]] = []  # (object-frame gel centre, class)
        self.rec = rr.RecordingStream("semanticfeels")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        sinks = [rr.FileSink(str(self.path))]
        if spawn and not has_display():
            log.warning("viz.live_spawn=true but no display here: writing %s only", self.path)
        elif spawn:
            rr.spawn(connect=False)
            sinks.append(rr.GrpcSink())
        self.rec.set_sinks(*sinks)
        colours = class_colours(self.class_names)
        context = [
            (i, name, tuple(int(c) for c in colours[i])) for i, name in enumerate(self.class_names)
        ]
        self.rec.log("world", rr.AnnotationContext(context), static=True)

    def on_frame(self, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper) -> None:
        rr = self.rr
        self.on_touches(frame, labels, world_T_object, mapper)  # sets the frame's time too
        self.rec.log("world/object", _transform(rr, world_T_object))
        if frame.camera is not None:
            self._log_camera(frame)
        centres = []
        for finger, reading in frame.tactile.items():
            self.rec.log(f"world/hand/{finger}", _transform(rr, reading.world_T_sensor))
            centres.append(_gel_centre(reading.world_T_sensor))
        if centres:
            self.rec.log("world/hand/gel_centres", rr.Points3D(np.stack(centres), radii=0.003))

    def on_touches(self, frame: Frame, labels: dict, world_T_object: np.ndarray, mapper) -> None:
        """Add the frame's classified touches (gel centres, object frame) and log them all;
        alone for the touches of a frame the mapper did not take (sensor.pace=realtime)."""
        rr = self.rr
        self.rec.set_time("frame", sequence=frame.index)
        self.rec.set_time("sensor_time", duration=float(frame.time_s))
        object_T_world = invert_pose(world_T_object)
        for finger, reading in frame.tactile.items():
            label = _touch_class(labels.get(finger))
            if label != NO_LABEL:
                centre = _gel_centre(reading.world_T_sensor)
                self.touches.append((transform_points(object_T_world, centre[None])[0], label))
        if self.touches:
            points = np.stack([p for p, _ in self.touches])
            classes = np.array([c for _, c in self.touches])
            self.rec.log(
                "world/object/touches", rr.Points3D(points, class_ids=classes, radii=0.002)
            )

    def _log_camera(self, frame: Frame) -> None:
        reading = frame.camera
        valid = np.isfinite(reading.depth) & (reading.depth > 0)  # backproject's test
        stride = max(1, int(np.ceil(np.sqrt(valid.sum() / max(1, self.camera_points)))))
        keep = np.zeros_like(valid)
        keep[::stride, ::stride] = valid[::stride, ::stride]
        points = transform_points(
            reading.world_T_camera, backproject(reading.depth, reading.intrinsics, keep)
        )
        self.rec.log(
            "world/camera/points", self.rr.Points3D(points, colors=reading.rgb[keep], radii=0.001)
        )

    def on_scores(self, frame_index: int, scores: dict | None, mapper) -> None:
        rr = self.rr
        self.rec.set_time("frame", sequence=frame_index)
        for key in STREAMED_SCORES:
            if scores and isinstance(scores.get(key), int | float):
                self.rec.log(f"scores/{key}", rr.Scalars(float(scores[key])))
        field = mapper.field
        center = field.center.detach().cpu().numpy().tolist()
        try:
            mesh = extract_mesh(
                field, field.bound, self.mesh_resolution, self.class_names, center=center
            )
        except NoDataError:
            return  # no surface yet: nothing to show
        vertices, faces = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.uint32)
        colours = np.asarray(mesh.visual.vertex_colors)[:, :3]
        self.rec.log(
            "world/object/map",
            rr.Mesh3D(vertex_positions=vertices, triangle_indices=faces, vertex_colors=colours),
        )
        uncertainty = _uncertainty_colours(mesh.vertex_attributes["uncertainty"])
        self.rec.log(
            "world/object/map_uncertainty",
            rr.Mesh3D(vertex_positions=vertices, triangle_indices=faces, vertex_colors=uncertainty),
        )

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


def _touch_class(label: TouchLabel | None) -> int:
    """Class index of a touch's classification, NO_LABEL without contact or class."""
    return label.label if label is not None and label.contact else NO_LABEL


def _gel_centre(world_T_sensor: np.ndarray) -> np.ndarray:
    """(3,) world point at the centre of a DIGIT's gel."""
    return transform_points(world_T_sensor, np.array([[0.0, 0.0, GEL_DISTANCE_M]]))[0]


def _transform(rr, pose: np.ndarray):
    """A rerun Transform3D of a 4x4 parent_T_child pose."""
    return rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3])


def _uncertainty_colours(uncertainty: np.ndarray) -> np.ndarray:
    """(N,) values in [0, 1] -> (N, 3) uint8 on matplotlib's viridis (dark: certain)."""
    from matplotlib import colormaps

    rgba = colormaps["viridis"](np.clip(np.asarray(uncertainty, np.float64), 0.0, 1.0))
    return (rgba[:, :3] * 255).round().astype(np.uint8)
