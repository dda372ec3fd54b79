"""The tactile depth network (source=net): shapes, checkpoint format, inference on a
simulated press through TactileDepth, the shipped asset, and real DIGIT frames."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from neuralfeels_sem.core.digit import DIGIT_INTRINSICS, GEL_DISTANCE_M
from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig
from neuralfeels_sem.perception.tactile_depth_metrics import depth_counts, summarise
from neuralfeels_sem.perception.tactile_depth_net import SHIPPED_CHECKPOINT, DepthNetPredictor
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import (
    load_checkpoint,
    save_checkpoint,
)
from neuralfeels_sem.perception.tactile_depth_net.model import build_model, preprocess, to_depth

SIZE = (64, 48)


def frames(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return (
        rng.integers(0, 256, (n, 320, 240, 3), dtype=np.uint8),
        rng.integers(0, 256, (n, 320, 240, 3), dtype=np.uint8),
    )


def test_model_maps_are_half_the_input_resolution() -> None:
    model = build_model(4).eval()
    images, backgrounds = frames(2)
    x = preprocess(images, backgrounds, (160, 120))
    assert x.shape == (2, 3, 160, 120) and x.dtype == torch.float32
    logits, press = model(x)
    assert logits.shape == press.shape == (2, 80, 60)
    assert (press >= 0).all()  # softplus: a press is never negative


def test_preprocess_refuses_mismatched_frames() -> None:
    images, backgrounds = frames(2)
    with pytest.raises(ValueError, match="images and backgrounds"):
        preprocess(images, backgrounds[:1], SIZE)


def test_to_depth_follows_the_simulator_convention_and_drops_specks() -> None:
    logits = torch.full((2, 320, 240), -5.0)
    logits[0, 100:140, 100:140] = 5.0  # 1600 px: a touch
    logits[1, 10:12, 10:12] = 5.0  # 4 px: noise
    press = torch.full((2, 320, 240), 1.0)  # mm
    depth = to_depth(logits, press, min_contact_px=150)
    assert depth.dtype == np.float32 and depth.shape == (2, 320, 240)
    assert np.allclose(depth[0, 100:140, 100:140], GEL_DISTANCE_M - 0.001)
    assert (depth[0] > 0).sum() == 1600 and not depth[1].any()


def test_checkpoint_round_trip_in_fp32_and_fp16(tmp_path: Path) -> None:
    torch.manual_seed(0)
    model = build_model(4).eval()
    images, backgrounds = frames(1)
    x = preprocess(images, backgrounds, SIZE)
    for fp16 in (False, True):
        path = save_checkpoint(tmp_path / "d.pt", model, SIZE, meta={"note": "t"}, fp16=fp16)
        ckpt = load_checkpoint(path)
        assert ckpt.input_size == SIZE and ckpt.width == 4 and ckpt.meta == {"note": "t"}
        with torch.no_grad():
            want, got = model(x)[1], ckpt.build()(x)[1]
        assert torch.allclose(want, got, atol=1e-2 if fp16 else 1e-6)
    depth = DepthNetPredictor(path).predict(images, backgrounds)
    assert depth.shape == (1, 320, 240) and depth.dtype == np.float32


def test_a_wrong_checkpoint_is_refused_naming_the_file(tmp_path: Path) -> None:
    model = build_model(4)
    other = tmp_path / "classifier.pt"
    torch.save({"format": "neuralfeels_sem.classifier/1", "state_dict": {}}, other)
    with pytest.raises(DataError, match=r"classifier\.pt is not a SemanticFeels tactile depth"):
        load_checkpoint(other)
    arch = save_checkpoint(tmp_path / "arch.pt", model, SIZE)
    payload = torch.load(arch, weights_only=True)
    torch.save({**payload, "arch": "resnet"}, arch)
    with pytest.raises(DataError, match=r"arch\.pt is a resnet"):
        load_checkpoint(arch)
    torch.save({**payload, "input_size": [8]}, arch)
    with pytest.raises(DataError, match=r"arch\.pt has input_size \[8\]"):
        load_checkpoint(arch)
    torch.save({**payload, "width": 8}, arch)  # tensors of width 4
    with pytest.raises(DataError, match=r"arch\.pt does not fit its own width 8"):
        DepthNetPredictor(arch).predict(*frames(1))
    with pytest.raises(DataError, match="does not exist"):
        DepthNetPredictor(tmp_path / "missing.pt").predict(*frames(1))


def test_the_shipped_checkpoint_loads() -> None:
    ckpt = load_checkpoint(SHIPPED_CHECKPOINT)
    model = ckpt.build()
    assert ckpt.meta["train_samples"] >= 1000
    report = json.loads((SHIPPED_CHECKPOINT.parent / "report.json").read_text())
    assert report["held_out"]["overall"]["contact_iou"] >= 0.85
    assert report["held_out"]["overall"]["depth_mae_mm"] <= 0.3
    assert sum(p.numel() for p in model.parameters()) < 1_000_000
    assert SHIPPED_CHECKPOINT.stat().st_size < 5_000_000


def test_net_source_finds_a_simulated_press_and_its_depth() -> None:
    """A 1.2 mm press of a 45 mm sphere, rendered by the simulator with a background the
    network never trained on: the predicted contact and depth match the simulator's."""
    from neuralfeels_sem.sim.digit_poses import pose_pressing
    from neuralfeels_sem.sim.tactile_renderer import DigitRenderer
    from neuralfeels_sem.sim.touch_sources import primitive_objects

    sphere = next(o for o in primitive_objects(["plastic"]) if "sphere_45mm" in o.name)
    renderer = DigitRenderer(sphere, seed=777)
    pose = pose_pressing(np.array([0.0, 0.0, 0.045]), np.array([0.0, 0.2, 1.0]), 0.0012, 0.4)
    try:
        render = renderer.render(np.eye(4), pose)
    finally:
        renderer.close()
    reading = TactileReading(
        "index", render.image, pose, DIGIT_INTRINSICS, background=renderer.background_image
    )
    source = TactileDepth(TactileDepthConfig("net"))
    depth = source(reading)
    figures = summarise(depth_counts(depth, render.depth, render.contact_mask))
    assert render.contact_mask.sum() > 5000
    assert figures["contact_iou"] > 0.85 and figures["depth_mae_mm"] < 0.3
    # A frame's fingers in one batch give what each gives alone (here: the press and an
    # unpressed gel).
    empty = TactileReading(
        "ring", renderer.background_image, pose, DIGIT_INTRINSICS, renderer.background_image
    )
    pressed, unpressed = source.batch([reading, empty])
    assert np.allclose(pressed, depth, atol=1e-6)
    assert np.array_equal(unpressed, source(empty)) and not unpressed.any()


def test_frames_without_change_skip_the_network(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only frames that differ from their background go through the network (in one
    batch); the others have no contact."""
    images, backgrounds = frames(3, seed=5)
    quiet = backgrounds[1]
    readings = [
        TactileReading(f, im, np.eye(4), DIGIT_INTRINSICS, background=bg)
        for f, im, bg in zip(
            ("index", "middle", "ring"), [images[0], quiet, images[2]], backgrounds
        )
    ]
    source = TactileDepth(TactileDepthConfig("net"))
    batches = []

    def predict(ims: np.ndarray, bgs: np.ndarray) -> np.ndarray:
        batches.append(len(ims))
        return np.full((len(ims), 320, 240), 0.02, np.float32)

    monkeypatch.setattr(source.net, "predict", predict)
    depths = source.batch(readings)
    assert batches == [2]
    assert depths[0].min() == depths[2].min() == 0.02
    assert depths[1].shape == (320, 240) and depths[1].dtype == np.float32 and not depths[1].any()
    assert not source(readings[1]).any() and batches == [2]
    assert source.unchanged == 2  # counted for metrics.json (perception)


def test_load_reads_the_network_only_for_the_net_source() -> None:
    # A run loads it before its clock starts (pipeline/mapping_session.py), not on a touch.
    net, gt = TactileDepth(TactileDepthConfig("net")), TactileDepth(TactileDepthConfig("gt"))
    net.load()
    gt.load()
    assert net.net._model is not None and gt.net._model is None
    # On the CPU the forward runs through ONNX Runtime, or as it is with cpu_runtime=torch
    # (graphs are for CUDA devices).
    assert type(net.net._forward).__name__ == "OnnxModule"
    eager = TactileDepth(TactileDepthConfig("net", cpu_runtime="torch"))
    eager.load()
    assert type(eager.net._forward).__name__ == "FullResolution"


def test_net_source_without_a_background_is_a_data_error() -> None:
    image = np.zeros((320, 240, 3), np.uint8)
    reading = TactileReading("ring", image, np.eye(4), DIGIT_INTRINSICS)
    with pytest.raises(DataError, match="source=net needs a no-contact background for ring"):
        TactileDepth(TactileDepthConfig("net"))(reading)


# ------------------------------------------------------------------ real DIGIT frames
def _rgb(path: Path) -> np.ndarray:
    image = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    if image.shape[:2] == (240, 320):
        image = np.ascontiguousarray(np.rot90(image))
    return cv2.resize(image, (240, 320), interpolation=cv2.INTER_AREA)


def test_contact_on_both_real_contact_frames(shared_data: Path) -> None:
    """Both grasp frames come from the sensor whose empty frame is aurova_bg_1.png (same
    LED layout and gel marks, checked by eye)."""
    real = shared_data / "digit_real"
    background = _rgb(real / "backgrounds" / "aurova_bg_1.png")
    images = np.stack([_rgb(real / "contact" / f"ycb_grasp_{i}.png") for i in (1, 2)])
    depth = DepthNetPredictor().predict(images, np.stack([background, background]))
    contact_px = (depth > 0).reshape(2, -1).sum(axis=1)
    assert (contact_px >= 2000).all(), contact_px


def test_no_contact_on_real_empty_frames_after_drift_and_noise(shared_data: Path) -> None:
    """Each real empty frame against itself as stored background, after what happens to a
    sensor between storing its background and a later frame: the LEDs and exposure drift
    (3 % gain, +3 grey levels) and fresh pixel noise (std 2 grey levels)."""
    folder = shared_data / "digit_real" / "backgrounds"
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg"))
    assert len(files) == 35
    rng = np.random.default_rng(0)
    backgrounds = np.stack([_rgb(p) for p in files])
    drifted = backgrounds.astype(np.float32) * 1.03 + 3.0
    drifted += rng.normal(0.0, 2.0, drifted.shape)
    images = np.clip(np.rint(drifted), 0, 255).astype(np.uint8)
    depth = DepthNetPredictor().predict(images, backgrounds)
    touched = [files[i].name for i in np.flatnonzero(depth.reshape(len(files), -1).any(axis=1))]
    assert touched == []
