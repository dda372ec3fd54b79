"""Camera segmentation without ground truth: hand removal, plane removal, clusters, sim IoU."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.frame import CameraReading, Frame
from neuralfeels_sem.core.geometry import Intrinsics
from neuralfeels_sem.mapping.frame_points import PointExtractor
from neuralfeels_sem.perception.camera_segmentation import CameraSegmenter, SegmentationConfig
from neuralfeels_sem.perception.hand_depth import HandDepthRenderer
from neuralfeels_sem.perception.segmentation_stats import mask_iou
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig

INTRINSICS = Intrinsics.from_fov(160, 120, 50.0)
CAMERA = np.eye(4)  # at the origin, looking along world +z


def _at(x: float, y: float, z: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


class BoxFinger:
    """A one-link 'hand': a 2 cm wide bar 30 cm in front of the camera (palm = identity)."""

    world_T_palm = np.eye(4)
    joint_limits = np.zeros((1, 2))

    def __init__(self) -> None:
        self.mesh = trimesh.creation.box(extents=(0.02, 0.2, 0.02))

    def link_meshes(self, q: np.ndarray) -> list[tuple[trimesh.Trimesh, np.ndarray]]:
        return [(self.mesh, _at(0.0, 0.0, 0.30))]


def _render(meshes) -> np.ndarray:
    renderer = HandDepthRenderer(INTRINSICS)
    depth = renderer.render(CAMERA, meshes)
    renderer.close()
    return depth


def _reading(depth: np.ndarray, mask: np.ndarray | None = None) -> CameraReading:
    rgb = np.zeros((*depth.shape, 3), np.uint8)
    return CameraReading(
        rgb=rgb, depth=depth, intrinsics=INTRINSICS, world_T_camera=CAMERA, mask=mask
    )


def _config(**overrides) -> SegmentationConfig:
    # The workspace: a box round the toy scene, in the (identity) palm frame.
    args = dict(workspace_min=[-0.2, -0.2, 0.1], workspace_max=[0.2, 0.2, 0.6])
    return SegmentationConfig(**{**args, **overrides})


def test_hand_removal_keeps_the_object_in_front_of_a_finger() -> None:
    hand = BoxFinger()
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.015)
    depth = _render([*hand.link_meshes(np.zeros(1)), (ball, _at(0.0, 0.03, 0.27))])
    finger_only = _render(hand.link_meshes(np.zeros(1)))
    ball_only = _render([(ball, _at(0.0, 0.03, 0.27))])
    result = CameraSegmenter(_config(), hand)(
        _reading(depth), np.zeros(1), np.array([[0, 0.03, 0.27]])
    )
    in_front = (ball_only > 0) & (finger_only > 0)  # the ball covers part of the finger
    assert in_front.sum() > 50
    assert result.mask[in_front].mean() > 0.9
    finger_seen = (finger_only > 0) & (ball_only == 0)
    assert not result.mask[finger_seen].any()
    assert mask_iou(result.mask, ball_only > 0) > 0.85


def test_a_table_is_removed_and_the_object_on_it_kept() -> None:
    table = trimesh.creation.box(extents=(1.0, 1.0, 0.01))
    tilt = trimesh.transformations.rotation_matrix(np.deg2rad(50), [1, 0, 0])
    tilt[:3, 3] = (0.0, 0.0, 0.45)
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    depth = _render([(table, tilt), (ball, _at(0.0, 0.0, 0.35))])
    ball_only = _render([(ball, _at(0.0, 0.0, 0.35))])
    # No hand: no workspace crop; only the plane and the clusters decide.
    result = CameraSegmenter(_config(), None)(_reading(depth), None, np.array([[0.0, 0.0, 0.35]]))
    assert result.found
    assert mask_iou(result.mask, ball_only > 0) > 0.9


def test_a_flat_object_face_is_not_taken_for_a_table() -> None:
    box = trimesh.creation.box(extents=(0.08, 0.08, 0.08))
    depth = _render([(box, _at(0.0, 0.0, 0.35))])
    result = CameraSegmenter(_config(), None)(_reading(depth), None, np.array([[0.045, 0.0, 0.35]]))
    assert mask_iou(result.mask, depth > 0) > 0.95


def test_a_frame_without_the_object_is_skipped_and_counted() -> None:
    wall = trimesh.creation.box(extents=(1.0, 1.0, 0.01))
    depth = _render([(wall, _at(0.0, 0.0, 0.5))])
    frame = Frame(
        index=0,
        time_s=0.0,
        world_T_object=_at(0.0, 0.0, 0.3),
        tactile={},
        camera=_reading(depth, mask=np.zeros(depth.shape, bool)),
        joint_positions=np.zeros(1),
    )
    extractor = PointExtractor(
        "segment", TactileDepth(TactileDepthConfig()), _config(), BoxFinger()
    )
    points = extractor(frame, frame.world_T_object)
    assert "camera" not in points  # never fused
    summary = extractor.stats.summary()
    assert summary["camera_frames_segmented"] == 1 and summary["camera_frames_no_object"] == 1
    assert summary["mask_iou_mean"] == 1.0  # nothing found where there is nothing


def test_a_joint_vector_of_the_wrong_length_is_refused() -> None:
    depth = _render(BoxFinger().link_meshes(np.zeros(1)))
    segmenter = CameraSegmenter(_config(), BoxFinger())
    with pytest.raises(
        ValueError, match="joint_positions has shape \\(16,\\) but the hand model has 1 joints"
    ):
        segmenter(_reading(depth), np.zeros(16), np.zeros((1, 3)))


@pytest.mark.parametrize(
    "key, value",
    [
        ("workspace_max", [-1.0, 1.0, 1.0]),
        ("hand_margin_m", 0.0),
        ("plane_min_share", 1.5),
        ("hand_dilation_px", -1),
    ],
)
def test_bad_settings_name_the_key(key: str, value) -> None:
    with pytest.raises(ValueError, match=key):
        SegmentationConfig(**{key: value})


def test_a_part_split_off_by_a_depth_jump_joins_the_body_it_touches() -> None:
    body = trimesh.creation.box(extents=(0.06, 0.06, 0.06))
    knob = trimesh.creation.box(extents=(0.02, 0.02, 0.01))
    # The knob sits on the body's front face (z = 0.37), 1 cm nearer the camera.
    scene = [(body, _at(0.0, 0.0, 0.40)), (knob, _at(0.0, 0.0, 0.365))]
    depth = _render(scene)
    knob_seen = np.abs(depth - 0.36) < 1e-3
    tip = np.array([[0.035, 0.0, 0.40]])  # at the body's side, over 4 cm from the knob
    args = dict(cluster_gap_m=0.005)  # the knob's 1 cm step splits it off in the image
    joined = CameraSegmenter(_config(**args), None)(_reading(depth), None, tip)
    split = CameraSegmenter(_config(cluster_merge_m=1e-4, **args), None)(_reading(depth), None, tip)
    assert knob_seen.sum() > 50
    assert joined.mask[knob_seen].mean() > 0.95
    assert split.mask[knob_seen].mean() < 0.05
    assert mask_iou(joined.mask, depth > 0) > 0.85  # less the boundary pixels round the knob


def test_a_cluster_far_from_every_fingertip_is_not_the_object() -> None:
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.02)
    depth = _render([(ball, _at(0.0, 0.0, 0.35))])
    tip = np.array([[0.0, 0.15, 0.35]])  # 13 cm from the ball's surface
    result = CameraSegmenter(_config(), None)(_reading(depth), None, tip)
    assert not result.found and not result.mask.any()
