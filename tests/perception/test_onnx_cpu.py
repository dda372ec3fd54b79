"""CPU inference through ONNX Runtime (perception/onnx_cpu.py): the same outputs as torch
within float rounding, at any batch size, cached on disk by checkpoint content; bad
settings and a missing package refused in one line."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.perception.classifier import MaterialClassifier
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint
from neuralfeels_sem.perception.classifier.inference import _folded
from neuralfeels_sem.perception.onnx_cpu import OnnxModule, onnx_module
from neuralfeels_sem.perception.tactile_depth import TactileDepthConfig
from neuralfeels_sem.perception.tactile_depth_net import DepthNetPredictor
from neuralfeels_sem.perception.tactile_depth_net.checkpoint import save_checkpoint
from neuralfeels_sem.perception.tactile_depth_net.model import build_model
from tests.perception.synthetic_tactile import CLASSES


def _classifier(path: Path) -> tuple[torch.nn.Module, list, object]:
    """The folded eager classifier of `path` and a counter of how often it was built."""
    model = _folded(load_checkpoint(path).build(torch.device("cpu")))
    built: list = []

    def build():
        built.append(1)
        return model

    return model, built, build


def test_the_exported_classifier_matches_torch_at_every_batch_size(
    untrained_checkpoint: Path, tmp_path: Path
) -> None:
    eager, _, build = _classifier(untrained_checkpoint)
    onnx = onnx_module(untrained_checkpoint, build, (3, 32, 32), cache=tmp_path)
    assert isinstance(onnx, OnnxModule)
    for batch in (1, 2, 5):
        x = torch.rand(batch, 3, 32, 32)
        with torch.inference_mode():
            want = eager(x)
        got = onnx(x)
        assert got.shape == want.shape and got.dtype == torch.float32
        assert torch.allclose(got, want, atol=1e-4, rtol=1e-4)


def test_the_export_is_cached_by_content_and_a_damaged_file_is_exported_over(
    untrained_checkpoint: Path, tmp_path: Path, caplog
) -> None:
    import shutil

    _, built, build = _classifier(untrained_checkpoint)
    cache = tmp_path / "cache"
    cache.mkdir()
    onnx_module(untrained_checkpoint, build, (3, 32, 32), cache=cache)
    (saved,) = cache.glob("*.onnx")
    copy = tmp_path / "elsewhere" / untrained_checkpoint.name
    copy.parent.mkdir()
    shutil.copy(untrained_checkpoint, copy)
    onnx_module(copy, build, (3, 32, 32), cache=cache)
    assert len(built) == 1  # the copy's content names the same file
    onnx_module(untrained_checkpoint, build, (3, 48, 48), cache=cache)
    assert len(built) == 2 and len(list(cache.glob("*.onnx"))) == 2  # another input size
    saved.write_bytes(b"not a graph")
    again = onnx_module(untrained_checkpoint, build, (3, 32, 32), cache=cache)
    assert len(built) == 3 and "exporting again" in caplog.text
    assert again(torch.rand(1, 3, 32, 32)).shape == (1, len(CLASSES))
    assert not list(cache.glob("*.tmp"))


def test_the_session_runs_with_the_runs_thread_count(
    untrained_checkpoint: Path, tmp_path: Path
) -> None:
    _, _, build = _classifier(untrained_checkpoint)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        onnx = onnx_module(untrained_checkpoint, build, (3, 32, 32), cache=tmp_path)
        options = onnx.session.get_session_options()
        assert options.intra_op_num_threads == 2 and options.inter_op_num_threads == 1
    finally:
        torch.set_num_threads(before)


def test_the_classifier_reads_the_same_under_either_cpu_runtime(
    untrained_checkpoint: Path,
) -> None:
    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, (6, 32, 32, 3), dtype=np.uint8)
    probs = {
        runtime: MaterialClassifier(
            CLASSES, checkpoint=str(untrained_checkpoint), device="cpu", cpu_runtime=runtime
        ).predict_images(images)
        for runtime in ("onnxruntime", "torch")
    }
    assert np.allclose(probs["onnxruntime"], probs["torch"], atol=1e-5)
    assert (probs["onnxruntime"].argmax(1) == probs["torch"].argmax(1)).all()


def test_the_tactile_depth_network_reads_the_same_under_either_cpu_runtime(
    tmp_path: Path,
) -> None:
    torch.manual_seed(0)
    path = save_checkpoint(tmp_path / "d.pt", build_model(4).eval(), (64, 48))
    rng = np.random.default_rng(1)
    background = rng.integers(60, 120, (320, 240, 3), dtype=np.uint8)
    images = np.stack([background, background])
    images[0, 100:200, 80:160] += 60  # a press on the first frame only
    backgrounds = np.stack([background, background])
    depths = {
        runtime: DepthNetPredictor(path, min_contact_px=0, cpu_runtime=runtime).predict(
            images, backgrounds
        )
        for runtime in ("onnxruntime", "torch")
    }
    assert depths["onnxruntime"].shape == (2, 320, 240)
    assert np.allclose(depths["onnxruntime"], depths["torch"], atol=1e-6)


def test_an_unknown_cpu_runtime_is_refused_naming_the_key() -> None:
    with pytest.raises(ValueError, match=r"classifier\.cpu_runtime='tensorrt' is unknown"):
        EfficientNetClassifierConfig(cpu_runtime="tensorrt")
    with pytest.raises(ValueError, match=r"tactile_depth\.cpu_runtime='jax' is unknown"):
        TactileDepthConfig(cpu_runtime="jax")
    with pytest.raises(ValueError, match=r"classifier\.cpu_runtime='x' is unknown"):
        MaterialClassifier(CLASSES, cpu_runtime="x")


def test_without_onnxruntime_the_error_says_what_to_install_or_set(
    untrained_checkpoint: Path, tmp_path: Path, monkeypatch
) -> None:
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import fails
    _, _, build = _classifier(untrained_checkpoint)
    with pytest.raises(ConfigError, match=r"pip install onnxruntime onnx.*cpu_runtime=torch"):
        onnx_module(untrained_checkpoint, build, (3, 32, 32), cache=tmp_path)
