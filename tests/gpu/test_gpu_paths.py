"""The GPU path (`make test-gpu`, marker `gpu`): the field, its optimiser, the tactile depth
network, the classifier and a whole map run on CUDA against the same work on the CPU.

The CPU side runs the fused CPU kernels (fields/hash_kernels.py), the GPU side the PyTorch
path, so these tests also hold the two implementations to each other. Tolerances: float32
rounding for one step; for a whole run, whose optimisation diverges once its sums are
added in another order, 5 points of mean-class matching and 0.05 of F-score.
"""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest
import torch

from neuralfeels_sem.fields import FieldAdam, SemanticField
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig
from neuralfeels_sem.perception.classifier.infer import MaterialClassifier
from neuralfeels_sem.perception.graphed import BUCKETS, GraphedModel
from neuralfeels_sem.perception.tactile_depth_net import DepthNetPredictor
from tests.helpers import TOY_MAPPING, run_cli

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU"),
]
RUN_TOLERANCE_PCT = 5.0
RUN_TOLERANCE_FSCORE = 0.05
# Graph replay vs eager logits: a padded bucket runs cuDNN's kernels for another batch size,
# with TF32 convolutions; seen on an H100: up to 4.4e-4 relative on logits of about 45.
GRAPH_RTOL, GRAPH_ATOL = 2e-3, 1e-3


def _field_after_steps(device: str, steps: int = 5) -> dict[str, torch.Tensor]:
    torch.manual_seed(0)
    field = SemanticField(SemanticFieldConfig(num_classes=4), bound=0.1).to(device)
    optimizer = FieldAdam(field.parameters(), lr=3e-3)
    generator = torch.Generator().manual_seed(1)
    for _ in range(steps):
        x = ((torch.rand(4096, 3, generator=generator) - 0.5) * 0.2).to(device)
        out = field(x)
        target = (x.norm(dim=1) - 0.05).unsqueeze(1)
        loss = (out["sdf"].reshape(target.shape) - target).pow(2).mean()
        loss = loss + out["material_logits"].pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return {k: v.detach().cpu() for k, v in field.state_dict().items()}


def test_field_steps_on_the_gpu_follow_the_cpu() -> None:
    cpu, gpu = _field_after_steps("cpu"), _field_after_steps("cuda")
    for name, value in cpu.items():
        torch.testing.assert_close(gpu[name], value, rtol=1e-3, atol=1e-5, msg=name)


def _tactile_frames() -> tuple[np.ndarray, np.ndarray]:
    """Four DIGIT-sized frames: a background and a bright blob pressed into three of them."""
    rng = np.random.default_rng(0)
    background = rng.integers(90, 110, (320, 240, 3)).astype(np.uint8)
    images = np.repeat(background[None], 4, axis=0)
    rows, cols = np.mgrid[:320, :240]
    for i, (r, c) in enumerate([(160, 120), (100, 80), (220, 160)]):
        blob = ((rows - r) ** 2 + (cols - c) ** 2) < 40**2
        images[i][blob] = np.clip(images[i][blob].astype(int) + 60 + 10 * i, 0, 255)
    return images, np.repeat(background[None], 4, axis=0)


def test_tactile_depth_network_on_the_gpu_matches_the_cpu() -> None:
    images, backgrounds = _tactile_frames()
    cpu = DepthNetPredictor(device="cpu").predict(images, backgrounds)
    gpu = DepthNetPredictor(device="cuda").predict(images, backgrounds)
    # The contact mask thresholds the network's output: rounding may flip a pixel at its
    # edge (seen: 1 of 307200 on an H100); every other pixel agrees to float rounding.
    off = np.abs(gpu - cpu) > 2e-5
    assert off.mean() <= 1e-4, f"{off.sum()} of {off.size} depth pixels differ"
    np.testing.assert_allclose(gpu[~off], cpu[~off], atol=2e-5)


def test_tactile_depth_graph_replays_give_the_eager_depths() -> None:
    images, backgrounds = _tactile_frames()
    graphed = DepthNetPredictor(device="cuda")
    eager = DepthNetPredictor(device="cuda", cuda_graphs=False)
    graphed.load()
    shape = (3, *graphed.input_size)
    assert graphed._forward.captured() == [(b, shape) for b in (1, 2, 4, 8)]  # when loaded
    for batch in (1, 3, 4):  # 3: padded to the bucket of 4
        got = graphed.predict(images[:batch], backgrounds[:batch])
        want = eager.predict(images[:batch], backgrounds[:batch])
        off = np.abs(got - want) > 2e-5  # as against the CPU: a mask edge pixel may flip
        assert off.mean() <= 1e-4, f"batch {batch}: {off.sum()} of {off.size} pixels differ"


def test_classifier_on_the_gpu_gives_the_cpu_labels() -> None:
    images, _ = _tactile_frames()
    frames = torch.from_numpy(images[:3]).permute(0, 3, 1, 2).float() / 255.0
    probs = {}
    for device in ("cpu", "cuda"):
        clf = MaterialClassifier(["plastic", "metal", "fabric", "wood"], device=device).open()
        model = clf._model
        size = (clf._ckpt.input_size,) * 2  # the CPU's ONNX graph takes this size alone
        crops = torch.nn.functional.interpolate(frames, size=size, mode="bilinear")
        with torch.inference_mode():
            probs[device] = model(crops.to(clf._device)).softmax(dim=1).cpu()
    # The CPU runs ONNX Runtime's graph, the GPU cuDNN's kernels (TF32 convolutions): on
    # an H200 the probabilities differed by up to 7.2e-4, the labels not at all.
    assert torch.equal(probs["cuda"].argmax(dim=1), probs["cpu"].argmax(dim=1))
    torch.testing.assert_close(probs["cuda"], probs["cpu"], rtol=0.0, atol=2e-3)


def test_graph_replays_give_the_eager_outputs_at_every_batch_size() -> None:
    clf = MaterialClassifier(["plastic", "metal", "fabric", "wood"], device="cuda").open()
    graphed = clf._model
    assert isinstance(graphed, GraphedModel)
    shape = (3, clf._ckpt.input_size, clf._ckpt.input_size)
    assert graphed.captured() == [(b, shape) for b in BUCKETS]  # every bucket, when opened
    generator = torch.Generator().manual_seed(0)
    with torch.inference_mode():
        for batch in (1, 3, 5, 3, 9, 64):  # padded buckets, a bucket replayed again
            x = torch.rand(batch, *shape, generator=generator).cuda()
            torch.testing.assert_close(
                graphed(x), graphed.model(x), rtol=GRAPH_RTOL, atol=GRAPH_ATOL
            )
        assert graphed.captured() == [(b, shape) for b in BUCKETS]  # replays, no new capture
        other = torch.rand(3, 3, 224, 224, generator=generator).cuda()  # another input size
        torch.testing.assert_close(
            graphed(other), graphed.model(other), rtol=GRAPH_RTOL, atol=GRAPH_ATOL
        )
    assert (4, (3, 224, 224)) in graphed.captured()  # a graph of its own


def test_a_capture_while_another_thread_trains_the_field() -> None:
    stop, errors = threading.Event(), []

    def train() -> None:
        try:
            while not stop.is_set():
                _field_after_steps("cuda", steps=2)
        except Exception as exc:  # noqa: BLE001 - reported by the assert below
            errors.append(exc)

    worker = threading.Thread(target=train)
    worker.start()
    try:
        clf = MaterialClassifier(["plastic", "metal", "fabric", "wood"], device="cuda").open()
        with torch.inference_mode():
            for batch in (1, 2, 5, 12):
                x = torch.rand(batch, 3, 224, 224, device="cuda")
                torch.testing.assert_close(
                    clf._model(x), clf._model.model(x), rtol=GRAPH_RTOL, atol=GRAPH_ATOL
                )
    finally:
        stop.set()
        worker.join()
    assert not errors, errors
    assert not clf._model._eager


def test_a_map_run_on_the_gpu_scores_as_the_cpu_run(tmp_path) -> None:  # noqa: ANN001
    scores = {}
    for device in ("cpu", "cuda"):
        out = tmp_path / device
        args = ["sensor.duration_s=3", f"device={device}", f"hydra.run.dir={out}", *TOY_MAPPING]
        result = run_cli(args, timeout=1200)
        assert result.returncode == 0, result.stderr[-3000:]
        scores[device] = json.loads((out / "metrics.json").read_text())
    cpu, gpu = scores["cpu"], scores["cuda"]
    assert gpu["machine"]["device"].startswith("cuda")
    for key in ("matching_mean_class_pct", "matching_pct"):
        assert abs(gpu[key] - cpu[key]) <= RUN_TOLERANCE_PCT, (key, gpu[key], cpu[key])
    assert abs(gpu["fscore_5mm"] - cpu["fscore_5mm"]) <= RUN_TOLERANCE_FSCORE
