"""EfficientNet-B0 builds per class count, loads local weights strictly, round-trips checkpoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from efficientnet_pytorch import EfficientNet

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.perception.classifier.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.perception.classifier.model import (
    HEAD_KEYS,
    build_model,
    fold_batch_norms,
    fold_same_padding,
    trace_for_cpu,
)
from neuralfeels_sem.perception.classifier.transforms import IMAGENET_MEAN, IMAGENET_STD


@pytest.fixture(scope="module")
def imagenet_like(tmp_path_factory) -> tuple[Path, dict]:
    """A state dict in efficientnet-pytorch's layout with a 1000-class head, as a user would have."""
    torch.manual_seed(1)
    state = EfficientNet.from_name("efficientnet-b0").state_dict()
    path = tmp_path_factory.mktemp("weights") / "efficientnet-b0.pth"
    torch.save(state, path)
    return path, state


@pytest.mark.parametrize("num_classes", [4, 3])
def test_model_outputs_one_logit_per_class(num_classes: int) -> None:
    model = build_model(num_classes).eval()
    with torch.no_grad():
        out = model(torch.zeros(2, 3, 64, 64))
    assert out.shape == (2, num_classes)


def test_fast_layout_gives_the_library_models_numbers() -> None:
    torch.manual_seed(0)
    model = build_model(4)
    reference = EfficientNet.from_name("efficientnet-b0", num_classes=4)
    reference.load_state_dict(model.state_dict())
    x = torch.rand(3, 3, 64, 64)
    for train_mode in (False, True):
        model.train(train_mode)
        reference.train(train_mode)
        with torch.no_grad():
            torch.manual_seed(1)  # the same dropout and drop-connect draws in train mode
            ours = model(x)
            torch.manual_seed(1)
            torch.testing.assert_close(ours, reference(x), rtol=1e-4, atol=1e-4)
    assert model._conv_stem.weight.is_contiguous(memory_format=torch.channels_last)


def test_backbone_loads_from_local_file_and_head_stays_new(imagenet_like) -> None:
    path, state = imagenet_like
    torch.manual_seed(0)
    fresh_head = build_model(4).state_dict()["_fc.weight"].clone()
    torch.manual_seed(0)
    model = build_model(4, weights=path)
    loaded = model.state_dict()
    for key, value in state.items():
        if key not in HEAD_KEYS:
            assert torch.equal(loaded[key], value), key
    assert loaded["_fc.weight"].shape == (4, 1280)
    assert torch.equal(loaded["_fc.weight"], fresh_head)


def test_head_is_loaded_when_class_count_matches(tmp_path: Path) -> None:
    source = build_model(4)
    path = tmp_path / "w.pth"
    torch.save(source.state_dict(), path)
    target = build_model(4, weights=path)
    assert torch.equal(target.state_dict()["_fc.weight"], source.state_dict()["_fc.weight"])


def test_weights_with_missing_or_misshaped_backbone_keys_are_rejected(
    imagenet_like, tmp_path: Path
) -> None:
    _, state = imagenet_like
    missing = {k: v for k, v in state.items() if k != "_conv_stem.weight"}
    torch.save(missing, tmp_path / "missing.pth")
    with pytest.raises(DataError, match="1 missing keys"):
        build_model(4, weights=tmp_path / "missing.pth")
    extra = dict(state, **{"_blocks.99.weight": torch.zeros(1)})
    torch.save(extra, tmp_path / "extra.pth")
    with pytest.raises(DataError, match="unexpected"):
        build_model(4, weights=tmp_path / "extra.pth")
    wrong = dict(state, **{"_conv_stem.weight": torch.zeros(16, 3, 3, 3)})
    torch.save(wrong, tmp_path / "wrong.pth")
    with pytest.raises(DataError, match="wrong shapes"):
        build_model(4, weights=tmp_path / "wrong.pth")
    with pytest.raises(DataError, match="does not exist"):
        build_model(4, weights=tmp_path / "absent.pth")


@pytest.mark.parametrize("fp16", [False, True])
def test_checkpoint_round_trip(tmp_path: Path, fp16: bool) -> None:
    torch.manual_seed(0)
    model = build_model(3).eval()
    path = save_checkpoint(
        tmp_path / "classifier.pt",
        model,
        ["a", "b", "c"],
        96,
        list(IMAGENET_MEAN),
        list(IMAGENET_STD),
        meta={"val_accuracy": 0.5},
        fp16=fp16,
    )
    ckpt = load_checkpoint(path)
    assert ckpt.class_names == ["a", "b", "c"] and ckpt.input_size == 96
    assert ckpt.mean == pytest.approx(IMAGENET_MEAN) and ckpt.meta == {"val_accuracy": 0.5}
    rebuilt = ckpt.build("cpu")
    x = torch.rand(2, 3, 96, 96)
    with torch.no_grad():
        a, b = model(x), rebuilt(x)
    if fp16:
        assert ckpt.state_dict["_fc.weight"].dtype == torch.float16
        np.testing.assert_allclose(torch.softmax(a, 1), torch.softmax(b, 1), atol=2e-2)
    else:
        assert torch.equal(a, b)


def test_not_a_checkpoint_is_a_data_error(tmp_path: Path) -> None:
    torch.save({"something": 1}, tmp_path / "x.pt")
    with pytest.raises(DataError, match="not a SemanticFeels classifier checkpoint"):
        load_checkpoint(tmp_path / "x.pt")
    (tmp_path / "garbage.pt").write_bytes(b"not a zip")
    with pytest.raises(DataError, match="not readable"):
        load_checkpoint(tmp_path / "garbage.pt")


def test_folding_the_batch_norms_keeps_the_predictions() -> None:
    torch.manual_seed(0)
    model = build_model(4)
    with torch.no_grad():  # running statistics and affine maps away from the identity
        for bn in (m for m in model.modules() if isinstance(m, torch.nn.BatchNorm2d)):
            bn.running_mean.uniform_(-0.5, 0.5)
            bn.running_var.uniform_(0.5, 2.0)
            bn.weight.uniform_(0.5, 1.5)
            bn.bias.uniform_(-0.2, 0.2)
    model.eval()
    x = torch.rand(3, 3, 64, 64).contiguous(memory_format=torch.channels_last)
    with torch.no_grad():
        before = model(x)
        folded = fold_batch_norms(model)
        after = folded(x)
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in folded.modules())
    torch.testing.assert_close(after, before, rtol=1e-4, atol=1e-4)
    with pytest.raises(ValueError, match="eval mode"):
        fold_batch_norms(build_model(4).train())


def test_folding_symmetric_same_padding_into_the_convolutions_keeps_the_outputs() -> None:
    from efficientnet_pytorch.utils import Conv2dStaticSamePadding

    torch.manual_seed(0)
    model = fold_batch_norms(build_model(4).eval())
    convs = [m for m in model.modules() if isinstance(m, Conv2dStaticSamePadding)]
    pads = [m.static_padding for m in convs if isinstance(m.static_padding, torch.nn.ZeroPad2d)]
    x = torch.rand(5, 3, 112, 112).contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        before = model(x)
        folded = fold_same_padding(model)
        after = folded(x)
    kept = [m for m in convs if isinstance(m.static_padding, torch.nn.ZeroPad2d)]
    # the stride-1 depthwise convolutions lose their pass, the asymmetric stride-2 ones keep it
    assert len(kept) < len(pads) and all(max(m.stride) == 2 for m in kept)
    assert all(m.padding != (0, 0) for m in convs if m not in kept and m.kernel_size != (1, 1))
    torch.testing.assert_close(after, before, rtol=1e-6, atol=1e-6)


def test_the_traced_cpu_model_gives_the_eager_outputs_at_any_batch(monkeypatch) -> None:
    torch.manual_seed(0)
    model = fold_same_padding(fold_batch_norms(build_model(4).eval()))
    traced = trace_for_cpu(model, 112)
    assert isinstance(traced, torch.jit.ScriptModule)
    x = torch.rand(5, 3, 112, 112).contiguous(memory_format=torch.channels_last)
    with torch.inference_mode():
        for batch in (1, 2, 5):  # traced at batch 1
            assert torch.equal(traced(x[:batch]), model(x[:batch]))
    with pytest.raises(ValueError, match="eval mode"):
        trace_for_cpu(build_model(4).train(), 112)

    def no_tracing(*args, **kwargs):
        raise RuntimeError("tracing is gone")

    monkeypatch.setattr(torch.jit, "trace", no_tracing)
    assert trace_for_cpu(model, 112) is model  # the eager model, as before
