"""Hash-grid encoding: exact interpolation, dense/hashed indexing, gradients, sparse grads."""

from __future__ import annotations

import pytest
import torch

from neuralfeels_sem.fields.hash_grid import HASH_PRIMES, HashGridConfig, HashGridEncoding, sum_rows


def _tiny(dtype=torch.float64, **kwargs) -> HashGridEncoding:
    args = dict(
        num_levels=3,
        features_per_level=2,
        base_resolution=2,
        per_level_scale=2.0,
        log2_table_size=6,
    )
    args.update(kwargs)
    enc = HashGridEncoding(HashGridConfig(**args)).to(dtype)
    with torch.no_grad():
        enc.table.normal_()  # well away from zero so exact checks are meaningful
    return enc


def test_levels_resolutions_and_dense_prefix() -> None:
    enc = HashGridEncoding(
        HashGridConfig(num_levels=3, base_resolution=2, per_level_scale=2.0, log2_table_size=6)
    )
    # Resolutions 2, 4, 8: vertices 27 and 125 and 729; only 27 <= 64 is dense.
    assert enc.resolutions == [2, 4, 8]
    assert enc.num_dense_levels == 1
    assert enc.level_rows == [27, 64, 64]
    # Hashed levels first at multiples of the table size, then the dense levels.
    assert enc.level_offsets == [128, 0, 64]
    assert enc.table.shape == (27 + 64 + 64, 2)
    assert enc.out_dim == 6
    # The paper's defaults at the CPU table size: 16 levels up to resolution 2047, 5 dense.
    enc = HashGridEncoding(HashGridConfig(log2_table_size=19))
    assert enc.resolutions[0] == 16 and enc.resolutions[-1] == 2047
    assert enc.num_dense_levels == 5
    assert all((r + 1) ** 3 <= 2**19 for r in enc.resolutions[:5])
    assert (enc.resolutions[5] + 1) ** 3 > 2**19


def test_interpolation_at_grid_corners_returns_stored_features() -> None:
    enc = _tiny()
    res = 2
    ijk = torch.cartesian_prod(*[torch.arange(res + 1)] * 3)  # every vertex of level 0
    x = ijk.to(torch.float64) / res
    out = enc(x)[:, :2]  # level 0 features
    dense_rows = ijk[:, 0] + ijk[:, 1] * (res + 1) + ijk[:, 2] * (res + 1) ** 2
    rows = dense_rows + enc.level_offsets[0]
    torch.testing.assert_close(out, enc.table[rows], rtol=0, atol=1e-12)


def test_hashed_level_corner_uses_the_instant_ngp_hash() -> None:
    enc = _tiny()
    level, res = 2, 8
    ijk = torch.tensor([[3, 5, 7], [8, 0, 1], [0, 0, 0]])
    x = ijk.to(torch.float64) / res
    h = (ijk[:, 0] * HASH_PRIMES[0]) ^ (ijk[:, 1] * HASH_PRIMES[1]) ^ (ijk[:, 2] * HASH_PRIMES[2])
    rows = (h % 64) + enc.level_offsets[level]
    torch.testing.assert_close(
        enc(x)[:, 2 * level : 2 * level + 2], enc.table[rows], rtol=0, atol=1e-12
    )


def test_midpoint_is_mean_of_the_cell_corners() -> None:
    enc = _tiny()
    res = 2
    lower = torch.tensor([1, 0, 1])
    x = ((lower + 0.5) / res).to(torch.float64)[None]
    corners = lower + torch.cartesian_prod(*[torch.arange(2)] * 3)
    rows = corners[:, 0] + corners[:, 1] * 3 + corners[:, 2] * 9 + enc.level_offsets[0]
    torch.testing.assert_close(enc(x)[0, :2], enc.table[rows].mean(0), rtol=0, atol=1e-12)


def test_interpolation_is_linear_along_an_edge() -> None:
    enc = _tiny()
    start = enc.level_offsets[0]
    a, b = enc.table[start], enc.table[start + 1]  # vertices (0,0,0) and (1,0,0) of level 0
    t = torch.tensor([0.0, 0.25, 0.7, 1.0], dtype=torch.float64)
    x = torch.stack([t / 2, torch.zeros_like(t), torch.zeros_like(t)], dim=-1)
    torch.testing.assert_close(
        enc(x)[:, :2], (1 - t)[:, None] * a + t[:, None] * b, rtol=0, atol=1e-12
    )


def test_upper_face_is_inside_the_grid() -> None:
    enc = _tiny()
    out = enc(torch.ones(1, 3, dtype=torch.float64))
    assert torch.isfinite(out).all()
    torch.testing.assert_close(
        out[0, :2], enc.table[enc.level_offsets[0] + 26], rtol=0, atol=1e-12
    )  # vertex (2,2,2)


def test_gradcheck_inputs_and_table() -> None:
    torch.manual_seed(0)
    enc = _tiny(sparse_grad=False)
    # Away from cell faces, where the encoding is smooth.
    x = (torch.rand(6, 3, dtype=torch.float64) * 0.8 + 0.1).requires_grad_(True)
    assert torch.autograd.gradcheck(
        lambda p, t: torch.func.functional_call(enc, {"table": t}, (p,)), (x, enc.table)
    )


def test_sparse_gradient_matches_dense_gradient() -> None:
    torch.manual_seed(0)
    enc = _tiny(dtype=torch.float32, log2_table_size=8)
    x = torch.rand(200, 3)
    target = torch.randn(200, enc.out_dim)
    grads = {}
    for sparse in (False, True):
        enc.sparse_grad = sparse
        enc.table.grad = None
        ((enc(x) - target) ** 2).sum().backward()
        grads[sparse] = enc.table.grad
    assert grads[True].is_sparse and not grads[False].is_sparse
    torch.testing.assert_close(grads[True].to_dense(), grads[False], rtol=1e-5, atol=1e-6)
    # Only the rows of the touched cells appear in the sparse gradient.
    touched = torch.unique(enc.corner_indices(x)[0])
    torch.testing.assert_close(torch.unique(grads[True].coalesce().indices()[0]), touched)


def test_deterministic_init_and_shapes() -> None:
    torch.manual_seed(3)
    a = HashGridEncoding(HashGridConfig(log2_table_size=10, init_scale=1e-3))
    torch.manual_seed(3)
    b = HashGridEncoding(HashGridConfig(log2_table_size=10, init_scale=1e-3))
    assert torch.equal(a.table, b.table)
    assert a.table.abs().max() <= 1e-3
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        a(torch.zeros(5, 2))
    with pytest.raises(ValueError, match="per_level_scale"):
        HashGridConfig(per_level_scale=0.5)
    with pytest.raises(ValueError, match="log2_table_size"):
        HashGridConfig(log2_table_size=40)


def test_sum_rows_matches_unique_and_index_add() -> None:
    g = torch.Generator().manual_seed(0)
    idx = torch.randint(0, 500, (3000,), generator=g)
    values = torch.randn(3000, 2, generator=g, dtype=torch.float64)
    rows, sums = sum_rows(idx, values, 500)
    expected_rows, inverse = torch.unique(idx, return_inverse=True)
    expected = torch.zeros(len(expected_rows), 2, dtype=torch.float64).index_add_(
        0, inverse, values
    )
    assert torch.equal(rows, expected_rows)
    torch.testing.assert_close(sums, expected, rtol=0, atol=1e-12)


def test_two_lookups_in_one_loss_accumulate_sparse_gradients() -> None:
    torch.manual_seed(0)
    enc = _tiny(dtype=torch.float32, log2_table_size=8)
    a, b = torch.rand(50, 3), torch.rand(70, 3)
    grads = {}
    for sparse in (False, True):
        enc.sparse_grad = sparse
        enc.table.grad = None
        (enc(a).square().sum() + 3 * enc(b).sum()).backward()
        grads[sparse] = enc.table.grad.to_dense()
    torch.testing.assert_close(grads[True], grads[False], rtol=1e-5, atol=1e-6)


def test_corner_indices_match_a_naive_reference() -> None:
    enc = HashGridEncoding(
        HashGridConfig(num_levels=5, base_resolution=3, per_level_scale=1.7, log2_table_size=9)
    )
    assert 0 < enc.num_dense_levels < enc.num_levels  # both kinds of level are covered
    x = torch.rand(40, 3, generator=torch.Generator().manual_seed(0))
    idx, weights = enc.corner_indices(x)
    mask = 2**enc.log2_table_size - 1
    for level, res in enumerate(enc.resolutions):
        cell = (x * res).floor().long().clamp(0, res - 1)
        frac = x * res - cell
        for k in range(8):
            corner = cell + torch.tensor([k & 1, (k >> 1) & 1, (k >> 2) & 1])
            if level < enc.num_dense_levels:
                row = corner[:, 0] + corner[:, 1] * (res + 1) + corner[:, 2] * (res + 1) ** 2
            else:
                h = (
                    corner[:, 0] * HASH_PRIMES[0]
                    ^ corner[:, 1] * HASH_PRIMES[1]
                    ^ corner[:, 2] * HASH_PRIMES[2]
                )
                row = h & mask
            assert torch.equal(idx[:, level, k], row + enc.level_offsets[level]), (level, k)
            w = torch.where(
                torch.tensor([k & 1, (k >> 1) & 1, (k >> 2) & 1]).bool(), frac, 1 - frac
            ).prod(-1)
            torch.testing.assert_close(weights[:, level, k], w)
    # Every level's rows stay inside its own block of the table.
    for level, (start, rows) in enumerate(zip(enc.level_offsets, enc.level_rows)):
        assert idx[:, level].min() >= start and idx[:, level].max() < start + rows


def test_fused_interpolation_equals_the_autograd_path_bit_for_bit() -> None:
    """Points without a gradient take the fused gather + interpolation; points that need
    one (the eikonal loss) take plain autograd: same features, same sparse table gradient."""
    torch.manual_seed(0)
    enc = HashGridEncoding(HashGridConfig(log2_table_size=12, init_scale=1e-2))
    x = torch.rand(700, 3, generator=torch.Generator().manual_seed(1))
    upstream = torch.randn(700, enc.out_dim, generator=torch.Generator().manual_seed(2))
    results = []
    for needs_grad in (False, True):
        enc.table.grad = None
        out = enc(x.clone().requires_grad_(needs_grad))
        (out * upstream).sum().backward()
        results.append((out.detach(), enc.table.grad))
    (fused, g_fused), (plain, g_plain) = results
    assert torch.equal(fused, plain)
    assert torch.equal(g_fused._indices(), g_plain._indices())
    assert torch.equal(g_fused._values(), g_plain._values())
