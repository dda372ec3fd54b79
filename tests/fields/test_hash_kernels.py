"""Fused CPU kernels (fields/hash_kernels.py) against the PyTorch path they replace."""

from __future__ import annotations

import numpy as np
import torch

from neuralfeels_sem.fields import FieldAdam, SemanticField
from neuralfeels_sem.fields import hash_kernels as kernels
from neuralfeels_sem.fields.hash_grid import HashGridConfig, HashGridEncoding
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig

# Resolutions 4, 6, 9, 13 dense (up to 14^3 rows), 20 and finer hashed into 2^12 rows.
SMALL = {"num_levels": 8, "base_resolution": 4, "per_level_scale": 1.5, "log2_table_size": 12}


def _encoding() -> HashGridEncoding:
    torch.manual_seed(0)
    enc = HashGridEncoding(HashGridConfig(init_scale=0.1, **SMALL))
    assert 0 < enc.num_dense_levels < enc.num_levels  # both kinds of level are exercised
    return enc


def _points(n: int, seed: int) -> torch.Tensor:
    x = torch.rand(n, 3, generator=torch.Generator().manual_seed(seed))
    # Both faces of the unit cube, where the last cell is used with offset 1.
    x[:4] = torch.tensor([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [1.0, 0.0, 0.5], [0.0, 1.0, 1.0]])
    return x


def _both_paths(enc: HashGridEncoding, run) -> tuple:  # noqa: ANN001
    results = []
    for fused in (True, False):
        enc.fused_cpu = fused
        enc.table.grad = None
        results.append(run())
    return tuple(results)


def test_corner_rows_and_weights_are_the_pytorch_paths() -> None:
    enc = _encoding()
    x = _points(500, seed=1)
    out, rows, weights = enc._encode_fused(x, keep_corners=True)
    idx, ref_weights = enc.corner_indices(x)
    assert np.array_equal(rows, idx.numpy()) and rows.dtype == np.int32
    assert np.array_equal(weights, ref_weights.numpy())
    enc.fused_cpu = False
    with torch.no_grad():
        torch.testing.assert_close(out, enc(x), rtol=0, atol=1e-7)


def test_query_and_training_features_agree_with_pytorch() -> None:
    enc = _encoding()
    x = _points(800, seed=2)
    with torch.no_grad():
        query, ref_query = _both_paths(enc, lambda: enc(x))
    train, ref_train = _both_paths(enc, lambda: enc(x).detach())
    torch.testing.assert_close(query, ref_query, rtol=0, atol=1e-7)
    torch.testing.assert_close(train, ref_train, rtol=0, atol=1e-7)


def test_sparse_table_gradient_agrees_with_pytorch() -> None:
    enc = _encoding()
    x = _points(800, seed=3)
    upstream = torch.randn(800, enc.out_dim, generator=torch.Generator().manual_seed(4))

    def gradient() -> torch.Tensor:
        (enc(x) * upstream).sum().backward()
        return enc.table.grad

    fused, reference = _both_paths(enc, gradient)
    assert fused.is_sparse
    reference = reference.coalesce()
    assert torch.equal(fused._indices(), reference.indices())  # sorted, distinct, same rows
    torch.testing.assert_close(fused._values(), reference.values(), rtol=1e-6, atol=1e-7)


def test_table_gradient_leaves_its_bitmap_clear_for_the_next_call() -> None:
    rows = np.array([[[5, 5, 64, 0, 700, 64, 3, 1]]], dtype=np.int32)
    weights = np.full((1, 1, 8), 0.5, dtype=np.float32)
    grad = np.array([[1.0, 2.0]], dtype=np.float32)
    bitmap, rank = np.zeros(11, dtype=np.uint64), np.empty(11, dtype=np.int64)
    distinct, sums = kernels.table_grad(rows, weights, grad, bitmap, rank, 2)
    assert distinct.tolist() == [0, 1, 3, 5, 64, 700]
    # Each row's sum: 0.5 x (1, 2) per lookup; rows 5 and 64 were looked up twice.
    np.testing.assert_array_equal(sums[:, 0], [0.5, 0.5, 0.5, 1.0, 1.0, 0.5])
    np.testing.assert_array_equal(sums[:, 1], 2 * sums[:, 0])
    assert not bitmap.any()


def test_point_gradients_against_a_fixed_table_agree_with_pytorch() -> None:
    enc = _encoding()
    enc.table.requires_grad_(False)  # as pose tracking holds the field
    x = _points(600, seed=5)
    upstream = torch.randn(600, enc.out_dim, generator=torch.Generator().manual_seed(6))

    def point_gradient() -> torch.Tensor:
        points = x.clone().requires_grad_(True)
        return torch.autograd.grad((enc(points) * upstream).sum(), points)[0]

    fused, reference = _both_paths(enc, point_gradient)
    assert fused.abs().sum() > 0
    torch.testing.assert_close(fused, reference, rtol=1e-4, atol=1e-5)


def test_points_and_table_both_needing_gradients_keep_the_autograd_path() -> None:
    """The eikonal term differentiates the point gradient once more, with respect to the
    table: only the PyTorch path supports that."""
    enc = _encoding()
    x = _points(50, seed=5).requires_grad_(True)
    (grad_x,) = torch.autograd.grad(enc(x).pow(2).sum(), x, create_graph=True)
    grad_x.pow(2).sum().backward()
    assert torch.isfinite(grad_x).all() and grad_x.abs().sum() > 0
    assert enc.table.grad is not None and enc.table.grad._values().abs().sum() > 0


def _train(fused: bool, steps: int = 8) -> dict[str, torch.Tensor]:
    torch.manual_seed(0)
    config = SemanticFieldConfig(num_classes=3, encoding=HashGridConfig(**SMALL))
    field = SemanticField(config, bound=0.1)
    field.encoding.fused_cpu = fused
    optimizer = FieldAdam(field.parameters(), lr=1e-2, weight_decay=1e-4)
    optimizer.fused_cpu = fused
    generator = torch.Generator().manual_seed(6)
    for _ in range(steps):
        x = (torch.rand(300, 3, generator=generator) - 0.5) * 0.2
        out = field(x)
        loss = (out["sdf"] - x.norm(dim=1) + 0.05).pow(2).mean() + out["material_logits"].pow(
            2
        ).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return {k: v.detach().clone() for k, v in field.state_dict().items()}


def test_training_with_fused_kernels_follows_the_pytorch_path() -> None:
    fused, reference = _train(True), _train(False)
    for name, value in reference.items():
        torch.testing.assert_close(fused[name], value, rtol=1e-4, atol=1e-6, msg=name)
