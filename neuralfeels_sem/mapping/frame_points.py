"""The surface points of one frame, in the object frame: the camera's and each touch's."""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from neuralfeels_sem.core.digit import GEL_DISTANCE_M
from neuralfeels_sem.core.frame import CameraReading, Frame
from neuralfeels_sem.perception.camera_segmentation import (
    CameraSegmenter,
    Segmentation,
    SegmentationConfig,
)
from neuralfeels_sem.perception.pointcloud import camera_points, tactile_points
from neuralfeels_sem.perception.segmentation_stats import SegmentationStats
from neuralfeels_sem.perception.tactile_depth import TactileDepth
from neuralfeels_sem.perception.tactile_depth_metrics import DepthCounts, depth_counts, summarise

# mapping.mapper.camera_mask: the simulator's object mask (an oracle), a segmentation from
# depth and the hand's model, or every valid pixel.
CAMERA_MASKS = ("gt", "segment", "none")


def fingertip_points(frame: Frame) -> np.ndarray:
    """(K, 3) world centres of the frame's DIGIT gels (where the object is being touched)."""
    tips = [
        r.world_T_sensor[:3, :3] @ np.array([0.0, 0.0, GEL_DISTANCE_M]) + r.world_T_sensor[:3, 3]
        for r in frame.tactile.values()
    ]
    return np.asarray(tips, np.float64).reshape(-1, 3)


@dataclasses.dataclass
class _Percepts:
    """One frame's perception, made once; counted in the running figures once, when mapped."""

    segmentation: Segmentation | None = None
    depths: dict[str, np.ndarray] | None = None
    segmentation_counted: bool = False
    depths_counted: bool = False


def _frame_key(frame: Frame) -> tuple:
    """A frame by index and readings: a frame whose readings were replaced is perceived anew."""
    return (frame.index, id(frame.camera), tuple(id(r) for r in frame.tactile.values()))


class PointExtractor:
    """Back-projects a frame's camera depth (inside its `camera_mask`) and each finger's
    contact depth (from `tactile_depth`) into object-frame points.

    With camera_mask="segment" the object mask comes from CameraSegmenter (built on first
    use from `segmentation` and `hand_model`); `stats` keeps its running figures, and a
    frame where it finds no object gives no camera points at all. Touches whose depth is
    perceived (tactile_depth.source != gt) are scored against the simulator's depth where
    it exists (`depth_counts`); `perception_summary()` gives both for metrics.json.
    """

    def __init__(
        self,
        camera_mask: str,
        tactile_depth: TactileDepth,
        segmentation: SegmentationConfig | None = None,
        hand_model: object | None = None,
    ) -> None:
        if camera_mask not in CAMERA_MASKS:
            raise ValueError(f"camera_mask={camera_mask!r}: use one of {', '.join(CAMERA_MASKS)}")
        self.camera_mask = camera_mask
        self.tactile_depth = tactile_depth
        # A plain copy of the settings, checked now: a bad one fails at construction,
        # not at the first segmented frame.
        given = segmentation or SegmentationConfig()
        self.segmentation = SegmentationConfig(
            **{f.name: getattr(given, f.name) for f in dataclasses.fields(SegmentationConfig)}
        )
        self.hand_model = hand_model
        self.segmenter: CameraSegmenter | None = None
        self.stats = SegmentationStats()
        # For the run's pictures: the latest segmented camera frame and, where the
        # simulator's mask scores it, the worst one (reading, mask[, IoU]).
        self.last_segmented: tuple[CameraReading, np.ndarray] | None = None
        self.worst_segmented: tuple[CameraReading, np.ndarray, float] | None = None
        self.depth_counts = DepthCounts()
        self.tactile_readings_scored = 0
        # Frames perceived and not yet superseded: ingestion and pose tracking ask for the
        # same frame, and a producer thread (pipeline/producer.py) perceives frames ahead of
        # the mapper; each frame is perceived once and counted once, when it is mapped.
        self._percepts: dict[tuple, _Percepts] = {}
        self._lock = threading.Lock()

    def __call__(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        """Object-frame surface points per source: `camera` and each finger in contact."""
        return self.extract(frame, world_T_object, every_pixel=False)[0]

    def load_models(self) -> None:
        """Load the perception networks now rather than on the first frame."""
        self.tactile_depth.load()

    def perceive(self, frame: Frame) -> None:
        """Segment the camera and infer the contact depths of `frame` now, ahead of mapping it.

        For a producer thread: the results wait for `extract` (the mapper's side), which
        counts them in the running figures; a frame dropped unmapped is `forget`-ten.
        """
        percepts = self._entry(frame)
        segments = self.camera_mask == "segment" and frame.camera is not None
        if segments and percepts.segmentation is None:
            percepts.segmentation = self._segment(frame)
        if percepts.depths is None:
            percepts.depths = self._infer_depths(frame)

    def forget(self, frame: Frame) -> None:
        """Drop what `perceive` kept for a frame that will not be mapped."""
        with self._lock:
            self._percepts.pop(_frame_key(frame), None)

    def object_mask(self, frame: Frame) -> np.ndarray | None:
        """The camera's object mask under `camera_mask` (None: every valid pixel).

        A frame is segmented once: pose tracking and ingestion ask for the same frame.
        """
        reading = frame.camera
        if self.camera_mask == "none":
            return None
        if self.camera_mask == "gt":
            return reading.mask
        percepts = self._entry(frame, mapped=True)
        if percepts.segmentation is None:
            percepts.segmentation = self._segment(frame)
        result = percepts.segmentation
        if not percepts.segmentation_counted:
            percepts.segmentation_counted = True
            self.stats.add(result, reading.depth, reading.mask)
            self.last_segmented = (reading, result.mask)
            iou = self.stats.last_iou
            if iou is not None and (self.worst_segmented is None or iou < self.worst_segmented[2]):
                self.worst_segmented = (reading, result.mask, iou)
        return result.mask

    def _segment(self, frame: Frame) -> Segmentation:
        if self.segmenter is None:
            self.segmenter = CameraSegmenter(self.segmentation, self.hand_model)
        return self.segmenter(frame.camera, frame.joint_positions, fingertip_points(frame))

    def _entry(self, frame: Frame, mapped: bool = False) -> _Percepts:
        """The frame's percepts (new when none); `mapped`: the mapper's side asks, so the
        frames before this one are done with (mapped or dropped) and are let go."""
        key = _frame_key(frame)
        with self._lock:
            if mapped:
                for old in [k for k in self._percepts if k[0] < frame.index]:
                    del self._percepts[old]
            return self._percepts.setdefault(key, _Percepts())

    def extract(
        self, frame: Frame, world_T_object: np.ndarray, every_pixel: bool
    ) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
        """The points per source and, with `every_pixel`, the points of all valid camera pixels.

        The space prior carves along every pixel's ray, mask or not: for it the camera is
        back-projected once, without its mask, and the surface points are the pixels inside
        the mask (the same points, in the same order, as camera_points(..., use_mask=True)).
        """
        out: dict[str, np.ndarray] = {}
        every = None
        reading = frame.camera
        mask = None if reading is None else self.object_mask(frame)
        if reading is not None and (mask is None or mask.any()):
            if every_pixel:
                every = camera_points(reading, world_T_object, use_mask=False)
                out["camera"] = every if mask is None else every[_valid_mask(reading, mask)]
            else:
                masked = dataclasses.replace(reading, mask=mask)
                out["camera"] = camera_points(masked, world_T_object, mask is not None)
        out.update(self.touch_points(frame, world_T_object))
        return out, every

    def touch_points(
        self, frame: Frame, world_T_object: np.ndarray, depths: dict | None = None
    ) -> dict[str, np.ndarray]:
        """The contact points per finger (none for a finger out of contact); `depths`: the
        frame's contact depths when already read (`contact_depths`)."""
        depths = self.contact_depths(frame) if depths is None else depths
        out = {}
        for finger, tactile in frame.tactile.items():
            pts = tactile_points(tactile, depths[finger], world_T_object)
            if len(pts):
                out[finger] = pts
        return out

    def contact_depths(self, frame: Frame) -> dict[str, np.ndarray]:
        """Each finger's contact depth from `tactile_depth` (one batch per frame), scored
        once against the simulator's where it exists."""
        percepts = self._entry(frame, mapped=True)
        if percepts.depths is None:
            percepts.depths = self._infer_depths(frame)
        depths = percepts.depths
        if not percepts.depths_counted and self.tactile_depth.source != "gt":
            for reading in frame.tactile.values():
                if reading.gt_depth is not None:
                    truth = reading.gt_contact_mask
                    counts = depth_counts(depths[reading.finger], reading.gt_depth, truth)
                    self.depth_counts += counts
                    self.tactile_readings_scored += 1
        percepts.depths_counted = True
        return depths

    def _infer_depths(self, frame: Frame) -> dict[str, np.ndarray]:
        return dict(zip(frame.tactile, self.tactile_depth.batch(list(frame.tactile.values()))))

    def state_dict(self) -> dict:
        """The running perception figures (plain numbers), so a resumed run's figures cover
        every segment."""
        return {
            "segmentation": dataclasses.asdict(self.stats),
            "depth_counts": dataclasses.asdict(self.depth_counts),
            "tactile_readings_scored": self.tactile_readings_scored,
            "tactile_readings_unchanged": self.tactile_depth.unchanged,
        }

    def load_state_dict(self, state: dict | None) -> None:
        """Restore `state_dict()`; None (a checkpoint written without it) starts afresh."""
        if state is None:
            return
        self.stats = SegmentationStats(**state["segmentation"])
        self.depth_counts = DepthCounts(**state["depth_counts"])
        self.tactile_readings_scored = int(state["tactile_readings_scored"])
        # Checkpoints from before the no-change test: none skipped the network.
        self.tactile_depth.unchanged = int(state.get("tactile_readings_unchanged", 0))

    def perception_summary(self) -> dict:
        """metrics.json["perception"]: how the perceived inputs compare with the simulator's
        ground truth (None where a source is the ground truth itself or none exists)."""
        camera = self.stats.summary()
        tactile = summarise(self.depth_counts)
        return {
            "camera_mask": self.camera_mask,
            "camera_mask_iou": camera["mask_iou_mean"],
            "camera_frames_segmented": camera["camera_frames_segmented"],
            "camera_frames_skipped": camera["camera_frames_no_object"],
            "segmentation_ms_mean": camera["segmentation_ms_mean"],
            "tactile_depth_source": self.tactile_depth.source,
            "tactile_readings_scored": self.tactile_readings_scored,
            "tactile_readings_unchanged": (
                self.tactile_depth.unchanged if self.tactile_depth.source == "net" else None
            ),
            "tactile_contact_iou": tactile["contact_iou"],
            "tactile_depth_mae_mm": tactile["depth_mae_mm"],
        }


def _valid_mask(reading: CameraReading, mask: np.ndarray) -> np.ndarray:
    """`mask` at the valid depth pixels, in backproject's row-major order."""
    if mask.shape != reading.depth.shape:
        raise ValueError(
            f"mask shape {mask.shape} does not match depth shape {reading.depth.shape}"
        )
    valid = np.isfinite(reading.depth) & (reading.depth > 0)
    return mask.astype(bool)[valid]
