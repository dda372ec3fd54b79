"""SemanticField: outputs, branches, gradients, clamping, chunking, config, and a fit."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from neuralfeels_sem.configs import to_config
from neuralfeels_sem.fields import FieldAdam, SemanticField, evaluate_chunked
from neuralfeels_sem.fields.hash_grid import HashGridConfig
from neuralfeels_sem.fields.heads import MaterialHeadConfig, SdfHeadConfig
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig
from tests.helpers import compose_config

TINY = HashGridConfig(num_levels=4, base_resolution=4, per_level_scale=1.5, log2_table_size=8)


def make_field(num_classes: int, bound: float = 0.1, **settings) -> SemanticField:
    """SemanticField from its config: `settings` over SemanticFieldConfig's defaults."""
    return SemanticField(SemanticFieldConfig(num_classes=num_classes, **settings), bound)


def _field(concat: bool = True, seed: int = 0, dtype=torch.float32, **kwargs) -> SemanticField:
    torch.manual_seed(seed)
    kwargs.setdefault("encoding", TINY)
    field = make_field(3, material=MaterialHeadConfig(concat_sdf_features=concat), **kwargs)
    with torch.no_grad():
        field.encoding.table.normal_(0.0, 0.5)  # a non-trivial field to test against
    return field.to(dtype)


def _points(n: int = 50, scale: float = 0.09, seed: int = 1, dtype=torch.float32) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return ((torch.rand(n, 3, generator=g) * 2 - 1) * scale).to(dtype)


def test_forward_keys_shapes_and_consistent_methods() -> None:
    field = _field()
    x = _points()
    out = field(x)
    assert set(out) == {"sdf", "material_logits", "sdf_features"}
    assert out["sdf"].shape == (50,)
    assert out["material_logits"].shape == (50, 3)
    assert out["sdf_features"].shape == (50, 64)
    torch.testing.assert_close(field.sdf(x), out["sdf"])
    torch.testing.assert_close(field.material_logits(x), out["material_logits"])
    assert torch.equal(field.predict_material(x), out["material_logits"].argmax(-1))
    assert field.predict_material(x).dtype == torch.long


@pytest.mark.parametrize("concat", [True, False])
def test_material_depends_on_sdf_features_only_with_concat(concat: bool) -> None:
    field = _field(concat=concat)
    x = _points()
    before = field.material_logits(x)
    with torch.no_grad():
        field.encoding.table.add_(1.0)  # changes z(x) everywhere
    after = field.material_logits(x)
    assert torch.allclose(before, after) is not concat
    expected_in = 16 + 3 + (64 if concat else 0) + 4 * 2  # SH, x, z(x), material grid
    assert field.material_head.mlp.in_dim == expected_in


def test_material_loss_leaves_the_sdf_branch_alone_unless_asked() -> None:
    for backprop in (False, True):
        torch.manual_seed(0)
        field = make_field(
            3,
            encoding=TINY,
            material=MaterialHeadConfig(concat_sdf_features=True, backprop_to_sdf=backprop),
        )
        field.material_logits(_points()).sum().backward()
        assert (field.encoding.table.grad is not None) is backprop
        assert (field.sdf_head.mlp.out.weight.grad is None) and (
            field.material_head.mlp.out.weight.grad is not None
        )


def test_sdf_is_in_metres_and_gradcheck_of_the_whole_field() -> None:
    torch.manual_seed(0)
    field = make_field(
        3,
        encoding=HashGridConfig(**{**TINY.__dict__, "sparse_grad": False}),
        # z(x) is detached by default (a constant to the material loss); let x flow through it.
        material=MaterialHeadConfig(concat_sdf_features=True, backprop_to_sdf=True),
    ).double()
    with torch.no_grad():
        field.encoding.table.normal_(0.0, 0.5)
    x = _points(8, dtype=torch.float64).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda p: field(p)["sdf"], (x,))
    assert torch.autograd.gradcheck(lambda p: field(p)["material_logits"], (x,))
    # The SDF head output scaled by the bound is the returned SDF.
    x_n = field.normalise(x)
    raw = field.sdf_head(field.encoding((x_n + 1) / 2))[0]
    torch.testing.assert_close(field.sdf(x), raw * 0.1)


def test_sdf_gradient_matches_finite_differences_and_supports_eikonal() -> None:
    field = _field(dtype=torch.float64)
    x = _points(10, dtype=torch.float64)
    sdf, grad = field.sdf_and_gradient(x)
    h = 1e-7
    for axis in range(3):
        e = torch.zeros(3, dtype=torch.float64)
        e[axis] = h
        fd = (field.sdf(x + e) - field.sdf(x - e)) / (2 * h)
        torch.testing.assert_close(grad[:, axis], fd, rtol=1e-5, atol=1e-8)
    torch.testing.assert_close(sdf, field.sdf(x))
    # Eikonal loss backpropagates into the (sparse) table through the gradient itself.
    ((grad.norm(dim=-1) - 1) ** 2).mean().backward()
    assert field.encoding.table.grad is not None and field.encoding.table.grad.is_sparse
    assert field.encoding.table.grad.coalesce().values().abs().sum() > 0
    with torch.no_grad():
        g2 = field.sdf_gradient(x, create_graph=False)
    assert g2.shape == (10, 3) and not g2.requires_grad
    torch.testing.assert_close(g2, grad.detach())


def test_points_outside_the_bound_are_clamped() -> None:
    field = _field()
    x = torch.tensor([[0.5, 0.0, 0.0], [0.0, -0.3, 0.2]])
    inside = torch.tensor([[0.1, 0.0, 0.0], [0.0, -0.1, 0.1]])
    torch.testing.assert_close(field.sdf(x), field.sdf(inside))
    assert torch.isfinite(field(x)["material_logits"]).all()


def test_center_and_bound_place_the_cube() -> None:
    a = _field(seed=5)
    torch.manual_seed(5)
    b = make_field(
        3, bound=0.2, center=[0.3, -0.1, 0.05], encoding=TINY, material=MaterialHeadConfig()
    )
    b.load_state_dict({k: v for k, v in a.state_dict().items() if k != "center"}, strict=False)
    x = _points()
    # Same normalised points -> same network outputs; the SDF scales with the bound.
    xb = x * 2 + torch.tensor([0.3, -0.1, 0.05])
    torch.testing.assert_close(b.sdf(xb), a.sdf(x) * 2)
    torch.testing.assert_close(b.material_logits(xb), a.material_logits(x))


def test_deterministic_given_the_seed() -> None:
    a, b = _field(seed=7), _field(seed=7)
    for (name, p), q in zip(a.state_dict().items(), b.state_dict().values()):
        assert torch.equal(p, q), name
    assert not torch.equal(a.sdf_head.mlp.out.weight, _field(seed=8).sdf_head.mlp.out.weight)


def test_bad_shapes_and_arguments_raise() -> None:
    field = _field()
    for bad in (torch.zeros(4), torch.zeros(4, 2), torch.zeros(2, 4, 3)):
        with pytest.raises(ValueError, match=r"\(N, 3\)"):
            field(bad)
        with pytest.raises(ValueError, match=r"\(N, 3\)"):
            field.sdf_gradient(bad)
    with pytest.raises(ValueError, match="num_classes"):
        SemanticFieldConfig(num_classes=1)
    with pytest.raises(ValueError, match="num_classes"):
        SemanticFieldConfig()  # the class count has no default: conf/model sets it
    with pytest.raises(ValueError, match="bound"):
        make_field(3, bound=0.0)
    with pytest.raises(ValueError, match="center"):
        SemanticFieldConfig(num_classes=3, center=[0.0, 0.0])


def test_evaluate_chunked_matches_one_pass() -> None:
    field = _field()
    x = _points(1000)
    torch.testing.assert_close(evaluate_chunked(field.sdf, x, chunk=64), field.sdf(x))
    chunked = evaluate_chunked(field, x, chunk=300)
    assert set(chunked) == {"sdf", "material_logits", "sdf_features"}
    torch.testing.assert_close(chunked["material_logits"], field(x)["material_logits"])
    assert not chunked["sdf"].requires_grad
    with pytest.raises(ValueError, match="chunk"):
        evaluate_chunked(field.sdf, x, chunk=0)


def test_config_builds_the_field_with_its_typed_blocks_and_the_computed_bound() -> None:
    cfg = compose_config(
        [
            "model.material.concat_sdf_features=false",
            "model.encoding.log2_table_size=10",
            "materials=[a,b,c,d,e]",
        ]
    )
    assert "bound" not in cfg.model  # computed from the object, not a setting
    field = SemanticField(to_config(SemanticFieldConfig, cfg.model), bound=0.07)
    assert isinstance(field, SemanticField)
    assert field.bound == 0.07 and field.num_classes == 5
    assert field.concat_sdf_features is False
    assert field.encoding.log2_table_size == 10 and field.encoding.sparse_grad is True
    assert field.sdf_head.hidden_dim == SdfHeadConfig().hidden_dim


@pytest.fixture
def one_thread():
    """Small batches run as fast on one thread, and far faster when the cores are shared."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.mark.parametrize("concat", [True, False])
def test_fits_a_two_material_sphere(concat: bool, one_thread) -> None:
    """SDF of a 5 cm sphere to < 2 mm near the surface; a top/bottom material split from
    1024 labelled surface points to >= 98% agreement on fresh surface points."""
    torch.manual_seed(0)
    radius, bound = 0.05, 0.1
    field = make_field(
        2,
        bound=bound,
        encoding=HashGridConfig(log2_table_size=14),
        material=MaterialHeadConfig(concat_sdf_features=concat),
    )
    opt = FieldAdam(field.parameters(), lr=1e-2)
    g = torch.Generator().manual_seed(1)
    labelled = F.normalize(torch.randn(1024, 3, generator=g), dim=-1) * radius
    labels = (labelled[:, 2] > 0).long()
    for _ in range(120):
        d = F.normalize(torch.randn(256, 3, generator=g), dim=-1)
        near = d * (radius + torch.randn(256, 1, generator=g) * 0.005)
        free = (torch.rand(256, 3, generator=g) * 2 - 1) * bound
        pts = torch.cat([d * radius, near, free])
        sdf_loss = (field.sdf(pts) - (pts.norm(dim=-1) - radius)).abs().mean() / bound
        material_loss = F.cross_entropy(field.material_logits(labelled), labels)
        opt.zero_grad()
        (sdf_loss + material_loss).backward()
        opt.step()
    d = F.normalize(torch.randn(4000, 3, generator=g), dim=-1)
    test = d * (radius + torch.randn(4000, 1, generator=g) * 0.002)
    with torch.no_grad():
        err = (field.sdf(test) - (test.norm(dim=-1) - radius)).abs().mean().item()
        agreement = (
            (field.predict_material(d * radius) == (d[:, 2] > 0).long()).float().mean().item()
        )
    assert err < 0.002
    assert agreement >= 0.98


def _grid_field(**material) -> SemanticField:
    torch.manual_seed(0)
    grid = {"grid_levels": 3, "grid_base_resolution": 4, "grid_log2_table_size": 8}
    return make_field(3, encoding=TINY, material=MaterialHeadConfig(**{**grid, **material}))


def test_material_grid_adds_its_features_to_the_material_input_only() -> None:
    field = _grid_field()
    grid = field.material_head.grid
    assert grid is not None and grid.out_dim == 3 * 2
    assert field.material_head.mlp.in_dim == 16 + 3 + 64 + 6
    assert _field().material_head.grid is not None  # the default has one
    paper = make_field(3, encoding=TINY, material=MaterialHeadConfig(grid_levels=0))
    assert paper.material_head.grid is None  # the paper's branch
    x = _points()
    sdf_before, logits_before = field.sdf(x), field.material_logits(x)
    with torch.no_grad():
        grid.table.normal_(0.0, 1.0)
    torch.testing.assert_close(field.sdf(x), sdf_before)
    assert not torch.allclose(field.material_logits(x), logits_before)


def test_material_grid_gets_row_sparse_gradients_from_the_material_loss_only() -> None:
    field = _grid_field()
    field.material_logits(_points()).sum().backward()
    assert field.material_head.grid.table.grad.is_sparse
    assert field.encoding.table.grad is None
    dense = make_field(
        3,
        encoding=HashGridConfig(**{**TINY.__dict__, "sparse_grad": False}),
        material=MaterialHeadConfig(grid_levels=2, grid_log2_table_size=8),
    )
    dense.material_logits(_points()).sum().backward()
    assert not dense.material_head.grid.table.grad.is_sparse  # follows model.encoding


def test_material_grid_gradcheck() -> None:
    torch.manual_seed(0)
    field = make_field(
        3,
        encoding=HashGridConfig(**{**TINY.__dict__, "sparse_grad": False}),
        # z(x) is detached from the material loss; leave it out so x flows only through
        # SH, x and the material grid.
        material=MaterialHeadConfig(
            concat_sdf_features=False, grid_levels=2, grid_base_resolution=4, grid_log2_table_size=8
        ),
    ).double()
    with torch.no_grad():
        field.material_head.grid.table.normal_(0.0, 0.5)
    x = _points(8, dtype=torch.float64).requires_grad_(True)
    assert torch.autograd.gradcheck(lambda p: field.material_logits(p), (x,))


@pytest.mark.parametrize(
    ("key", "value"),
    [("grid_levels", -1), ("grid_base_resolution", 0), ("grid_per_level_scale", 0.5),
     ("grid_log2_table_size", 3)],
)  # fmt: skip
def test_material_grid_settings_are_range_checked(key: str, value) -> None:
    with pytest.raises(ValueError, match=f"model.material.{key}="):
        MaterialHeadConfig(**{"grid_levels": 2, key: value})


def test_material_logits_for_the_last_rows_only_equal_those_of_every_row() -> None:
    field = _field()
    x = _points(40)
    every, last = field(x), field(x, material_from=30)
    assert last["material_logits"].shape == (10, 3)
    torch.testing.assert_close(last["material_logits"], every["material_logits"][30:])
    torch.testing.assert_close(last["sdf"], every["sdf"])
    assert field(x, material_from=40)["material_logits"].shape == (0, 3)
    with pytest.raises(ValueError, match="material_from"):
        field(x, material_from=41)
