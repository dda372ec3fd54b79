"""FieldAdam: dense path equals torch Adam, sparse path is exact lazy Adam, state round trips."""

from __future__ import annotations

import io
import math

import pytest
import torch
from hydra.utils import instantiate

from neuralfeels_sem.fields import FieldAdam, SemanticField
from neuralfeels_sem.fields.hash_grid import HashGridConfig
from neuralfeels_sem.fields.optim import moments
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig


def tiny(num_classes: int, **encoding) -> SemanticFieldConfig:
    return SemanticFieldConfig(num_classes=num_classes, encoding=HashGridConfig(**encoding))


def _sparse(rows: torch.Tensor, values: torch.Tensor, shape: tuple[int, int]) -> torch.Tensor:
    return torch.sparse_coo_tensor(rows[None], values, shape, check_invariants=True)


def test_dense_path_equals_torch_adam() -> None:
    torch.manual_seed(0)
    a = torch.randn(40, 3, requires_grad=True)
    b = a.detach().clone().requires_grad_(True)
    opt_a = FieldAdam([a], lr=0.05, betas=(0.8, 0.99), eps=1e-6, weight_decay=0.01)
    opt_b = torch.optim.Adam([b], lr=0.05, betas=(0.8, 0.99), eps=1e-6, weight_decay=0.01)
    for _ in range(25):
        g = torch.randn(40, 3)
        a.grad, b.grad = g.clone(), g.clone()
        opt_a.step()
        opt_b.step()
    torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)


def test_sparse_path_with_every_row_equals_the_dense_path() -> None:
    torch.manual_seed(0)
    a = torch.randn(30, 2, requires_grad=True)
    b = a.detach().clone().requires_grad_(True)
    opt_a, opt_b = FieldAdam([a], lr=0.1), FieldAdam([b], lr=0.1)
    for _ in range(10):
        g = torch.randn(30, 2)
        # Every row once, plus duplicates of some rows that coalescing must sum.
        rows = torch.cat([torch.randperm(30), torch.tensor([3, 3, 7])])
        values = torch.cat([g[rows[:30]], torch.zeros(3, 2)])
        a.grad = _sparse(rows, values, (30, 2))
        b.grad = g
        opt_a.step()
        opt_b.step()
    torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-7)


def test_a_sparse_state_also_takes_dense_gradients() -> None:
    torch.manual_seed(0)
    a = torch.randn(10, 2, requires_grad=True)
    b = a.detach().clone().requires_grad_(True)
    opt_a, opt_b = (
        FieldAdam([a], lr=0.1, weight_decay=0.1),
        torch.optim.Adam([b], lr=0.1, weight_decay=0.1),
    )
    for step in range(6):
        g = torch.randn(10, 2)
        # Sparse first (state in `moments`), then dense: the same Adam trajectory.
        a.grad = _sparse(torch.arange(10), g, (10, 2)) if step < 3 else g.clone()
        b.grad = g.clone()
        opt_a.step()
        opt_b.step()
    assert "moments" in opt_a.state[a]
    torch.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)


def test_sparse_path_is_lazy_adam() -> None:
    """Rows outside a step's gradient keep their value and moments; touched rows follow
    Adam with per-parameter bias correction (checked against a float64 reference)."""
    torch.manual_seed(0)
    n, lr, b1, b2, eps = 20, 0.1, 0.9, 0.999, 1e-8
    p = torch.randn(n, 2, dtype=torch.float64, requires_grad=True)
    ref = p.detach().clone()
    m, v = torch.zeros_like(ref), torch.zeros_like(ref)
    opt = FieldAdam([p], lr=lr, eps=eps)
    for t in range(1, 16):
        rows = torch.randperm(n)[:6]
        g = torch.randn(6, 2, dtype=torch.float64)
        untouched = torch.ones(n, dtype=torch.bool)
        untouched[rows] = False
        before = p.detach().clone()
        p.grad = _sparse(rows, g, (n, 2))
        opt.step()
        assert torch.equal(p.detach()[untouched], before[untouched])
        m[rows] = b1 * m[rows] + (1 - b1) * g
        v[rows] = b2 * v[rows] + (1 - b2) * g * g
        m_hat, v_hat = m[rows] / (1 - b1**t), v[rows] / (1 - b2**t)
        ref[rows] -= lr * m_hat / (v_hat.sqrt() + eps)
        torch.testing.assert_close(p.detach(), ref, rtol=1e-10, atol=1e-12)
    first, second = moments(opt.state[p])
    torch.testing.assert_close(first, m, rtol=1e-12, atol=1e-15)
    torch.testing.assert_close(second, v, rtol=1e-12, atol=1e-15)


def _train(field: SemanticField, opt: torch.optim.Optimizer, steps: int, seed: int) -> None:
    g = torch.Generator().manual_seed(seed)
    for _ in range(steps):
        x = (torch.rand(128, 3, generator=g) * 2 - 1) * 0.1
        out = field(x)
        loss = (out["sdf"] - (x.norm(dim=-1) - 0.05)).abs().mean() + out[
            "material_logits"
        ].square().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()


def test_state_dict_round_trip_resumes_exactly() -> None:
    def make() -> tuple[SemanticField, FieldAdam]:
        torch.manual_seed(0)
        field = SemanticField(tiny(3, num_levels=4, log2_table_size=10), bound=0.1)
        return field, FieldAdam(field.parameters(), lr=1e-2)

    field_a, opt_a = make()
    _train(field_a, opt_a, 6, seed=1)
    _train(field_a, opt_a, 6, seed=2)

    field_b, opt_b = make()
    _train(field_b, opt_b, 6, seed=1)
    buffer = io.BytesIO()
    torch.save({"field": field_b.state_dict(), "optim": opt_b.state_dict()}, buffer)
    buffer.seek(0)
    saved = torch.load(buffer, weights_only=True)
    field_c, opt_c = make()
    field_c.load_state_dict(saved["field"])
    opt_c.load_state_dict(saved["optim"])
    _train(field_c, opt_c, 6, seed=2)
    for (name, a), c in zip(field_a.state_dict().items(), field_c.state_dict().values()):
        assert torch.equal(a, c), name


def test_partial_factory_from_config_and_bad_arguments() -> None:
    factory = instantiate(
        {"_target_": "neuralfeels_sem.fields.optim.FieldAdam", "_partial_": True, "lr": 3e-3}
    )
    field = SemanticField(tiny(2, num_levels=2, log2_table_size=8), bound=0.1)
    opt = factory(field.parameters())
    assert isinstance(opt, FieldAdam) and opt.param_groups[0]["lr"] == 3e-3
    assert math.isclose(opt.param_groups[0]["betas"][1], 0.999)
    for kwargs in ({"lr": -1.0}, {"betas": (1.0, 0.9)}, {"eps": -1.0}, {"weight_decay": -0.1}):
        with pytest.raises(ValueError):
            FieldAdam(field.parameters(), **kwargs)
    # Plain torch Adam needs dense table gradients: the dense option gives them.
    dense = SemanticField(tiny(2, num_levels=2, log2_table_size=8, sparse_grad=False), bound=0.1)
    adam = torch.optim.Adam(dense.parameters(), lr=1e-3)
    dense.sdf(torch.zeros(4, 3)).sum().backward()
    adam.step()
