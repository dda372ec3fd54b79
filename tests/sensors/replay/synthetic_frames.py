"""Frames with random content and every optional field filled, for round-trip tests."""

from __future__ import annotations

import numpy as np

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS
from neuralfeels_sem.core.frame import CameraReading, Frame, TactileReading
from neuralfeels_sem.core.geometry import Intrinsics, rotation_matrix
from neuralfeels_sem.core.hand import FINGERS

CAMERA_INTRINSICS = Intrinsics(fx=120.0, fy=121.0, cx=39.5, cy=29.5, width=80, height=60)


def random_pose(rng: np.random.Generator) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rotation_matrix(rng.normal(size=3), rng.uniform(-np.pi, np.pi))
    pose[:3, 3] = rng.normal(scale=0.1, size=3)
    return pose


def make_frames(
    count: int, seed: int = 0, gt: bool = True, fingers: tuple[str, ...] = FINGERS
) -> list[Frame]:
    rng = np.random.default_rng(seed)
    backgrounds = {f: rng.integers(0, 256, (320, 240, 3), dtype=np.uint8) for f in fingers}
    frames = []
    for index in range(count):
        tactile = {}
        for finger in fingers:
            contact = rng.random((320, 240)) > 0.7
            tactile[finger] = TactileReading(
                finger=finger,
                image=rng.integers(0, 256, (320, 240, 3), dtype=np.uint8),
                world_T_sensor=random_pose(rng),
                intrinsics=DIGIT_INTRINSICS,
                background=backgrounds[finger],
                gt_contact_mask=contact if gt else None,
                gt_depth=(contact * rng.uniform(0.018, 0.02, (320, 240))).astype(np.float32)
                if gt
                else None,
                gt_material=np.where(contact, rng.integers(0, 4, (320, 240)), -1).astype(np.int16)
                if gt
                else None,
            )
        depth = rng.uniform(0.2, 0.6, (60, 80)).astype(np.float32)
        depth[rng.random((60, 80)) > 0.9] = 0.0
        camera = CameraReading(
            rgb=rng.integers(0, 256, (60, 80, 3), dtype=np.uint8),
            depth=depth,
            intrinsics=CAMERA_INTRINSICS,
            world_T_camera=random_pose(rng),
            mask=(rng.random((60, 80)) > 0.5) if gt else None,
            name="front-left",
        )
        frames.append(
            Frame(
                index=index,
                time_s=index * 0.1 + float(rng.uniform(0, 1e-3)),
                world_T_object=random_pose(rng),
                tactile=tactile,
                camera=camera,
                gt_world_T_object=random_pose(rng) if gt else None,
                joint_positions=rng.uniform(-0.5, 1.5, 16),
            )
        )
    return frames


def assert_frames_equal(a: Frame, b: Frame) -> None:
    """Every field identical (arrays bit-exact)."""
    assert (a.index, a.time_s) == (b.index, b.time_s)
    for name in ("world_T_object", "gt_world_T_object", "joint_positions"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert sorted(a.tactile) == sorted(b.tactile)
    for finger, ta in a.tactile.items():
        tb = b.tactile[finger]
        assert ta.intrinsics == tb.intrinsics
        for name in (
            "image",
            "world_T_sensor",
            "background",
            "gt_contact_mask",
            "gt_depth",
            "gt_material",
        ):
            x, y = getattr(ta, name), getattr(tb, name)
            assert (x is None) == (y is None), f"{finger}.{name}"
            if x is not None:
                assert x.dtype == y.dtype or name == "world_T_sensor", (
                    f"{finger}.{name} dtype {x.dtype} != {y.dtype}"
                )
                np.testing.assert_array_equal(x, y, err_msg=f"{finger}.{name}")
    assert (a.camera is None) == (b.camera is None)
    if a.camera is not None:
        ca, cb = a.camera, b.camera
        assert (ca.intrinsics, ca.name) == (cb.intrinsics, cb.name)
        for name in ("rgb", "depth", "world_T_camera", "mask"):
            x, y = getattr(ca, name), getattr(cb, name)
            assert (x is None) == (y is None), name
            if x is not None:
                np.testing.assert_array_equal(x, y, err_msg=f"camera.{name}")
                assert x.dtype == y.dtype or name == "world_T_camera", name
