"""Word-sized row gathers and scatters equal torch's index_select / index_copy_ bit for bit."""

from __future__ import annotations

import pytest
import torch

from neuralfeels_sem.fields import FieldAdam, SemanticField, row_ops
from neuralfeels_sem.fields.hash_grid import HashGridConfig
from neuralfeels_sem.fields.row_ops import copy_rows_, gather_rows
from neuralfeels_sem.fields.semantic_field import SemanticFieldConfig


@pytest.mark.parametrize(
    "shape",
    [(50, 2), (50, 2, 2), (50, 3), (50, 1), (50, 4, 2)],
    ids=["8-byte rows", "16-byte rows", "12-byte rows", "4-byte rows", "32-byte rows"],
)
def test_gather_and_copy_equal_torch(shape: tuple[int, ...]) -> None:
    g = torch.Generator().manual_seed(0)
    table = torch.randn(shape, generator=g)
    idx = torch.randint(shape[0], (77,), generator=g)
    assert torch.equal(gather_rows(table, idx), table.index_select(0, idx))
    rows = torch.randperm(shape[0], generator=g)[:20]
    values = torch.randn((20, *shape[1:]), generator=g)
    expected = table.clone().index_copy_(0, rows, values)
    assert torch.equal(copy_rows_(table.clone(), rows, values), expected)


def test_views_and_strided_tensors_take_the_ordinary_path() -> None:
    base = torch.randn(40, 2, 2)
    half = base[:, 0]  # (40, 2) but not contiguous
    idx = torch.tensor([3, 1, 3, 39])
    assert torch.equal(gather_rows(half, idx), half.index_select(0, idx))
    shifted = torch.randn(81)[1:].view(40, 2)  # starts half a row into its storage
    assert torch.equal(gather_rows(shifted, idx), shifted.index_select(0, idx))
    strided_values = torch.randn(4, 2, 2)[:, 1]
    target = torch.randn(40, 2)
    expected = target.clone().index_copy_(0, idx[:3].unique(), strided_values[:2])
    assert torch.equal(copy_rows_(target, idx[:3].unique(), strided_values[:2]), expected)


def _train(steps: int) -> dict[str, torch.Tensor]:
    torch.manual_seed(0)
    config = SemanticFieldConfig(num_classes=3, encoding=HashGridConfig(log2_table_size=12))
    field = SemanticField(config, bound=0.1)
    opt = FieldAdam(field.parameters(), lr=1e-2)
    g = torch.Generator().manual_seed(1)
    for _ in range(steps):
        x = (torch.rand(512, 3, generator=g) * 2 - 1) * 0.1
        out = field(x)
        loss = (out["sdf"] - (x.norm(dim=1) - 0.05)).abs().mean()
        loss = loss + torch.nn.functional.cross_entropy(
            out["material_logits"], (x[:, 0] > 0).long()
        )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    state = {f"field.{k}": v.clone() for k, v in field.state_dict().items()}
    state["moments"] = opt.state[field.encoding.table]["moments"].clone()
    return state


def test_training_with_word_rows_is_bit_identical(monkeypatch: pytest.MonkeyPatch) -> None:
    fast = _train(6)
    monkeypatch.setattr(row_ops, "_WORD_DTYPES", {})  # every gather on torch's ordinary path
    plain = _train(6)
    assert fast.keys() == plain.keys()
    for key in fast:
        assert torch.equal(fast[key], plain[key]), key
