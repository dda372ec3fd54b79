"""How a checkpoint stores the field's hash tables and their Adam moments (most of its bytes).

A table row is "updated" once the optimiser has given it a moment (a training point fell
in one of its cells); the others still hold their initial values and zero moments. For
each table parameter (2-D or more, at least MIN_PACKED_ROWS rows) the checkpoint stores:
- which rows were updated (one bit per row);
- the updated rows of the table and of both moments: `exact` as float32 (a resumed run
  continues bit for bit), or `compact`: the table in float16, the moments as 8-bit codes
  of log2(sqrt(v)) and of m / sqrt(v) (bounded by Adam's own arithmetic: |m| <= 7.3 sqrt(v)
  for betas (0.9, 0.999)), i.e. 4 bytes per value instead of 12, then deflated
  (mapping/byte_planes.py). float16 moments would underflow (m ~ 1e-8, v ~ 1e-16 at the
  default learning rate); these codes do not;
- the other rows: nothing when the field was built by mapping/field_init.build_field
  (they are drawn again from the random state it was constructed from, checked against a
  hash of their values), else their values (float32 exact, float16 compact).
`auto` (what a mapping run writes) is `exact` while that costs at most EXACT_LIMIT_BYTES,
else `compact`. Measured on the default run (docs/usage.md, bench_checkpoint.py).
`compact` also stores the memory's point clouds (keyframe points, touch points, their axes
and weights) as float16 and the touch points' labels as int8; `decode` gives them back
their own dtypes.
"""

from __future__ import annotations

import copy
import hashlib
import warnings

import numpy as np
import torch
from torch import Tensor, nn

from neuralfeels_sem.fields.row_ops import gather_rows
from neuralfeels_sem.mapping.byte_planes import pack_planes, unpack_planes
from neuralfeels_sem.mapping.field_init import init_rng_state, initial_state, initial_tables

STORAGES = ("auto", "exact", "compact")
# `auto` stays exact up to this many bytes of tables and moments (the 40 MB target).
EXACT_LIMIT_BYTES = 40_000_000
# Smaller parameters (the MLPs) are stored as they are: packing them would save nothing.
MIN_PACKED_ROWS = 4096
PACKED_KEY = "packed_tables"
INIT_KEY = "init_rng_state"
NARROWED_KEY = "narrowed_memory"  # "part/key" -> the dtype a narrowed list had
# What `compact` narrows in the memory's state (MapMemory.state_dict) and to which dtype:
# float16 keeps a point to about 0.06 mm within the 0.1 m of an object, a unit axis or a
# weight to 1e-3; labels are class indices or -1.
_NARROWED = {
    ("keyframes", "points"): torch.float16,
    ("touches", "points"): torch.float16,
    ("touches", "axes"): torch.float16,
    ("touches", "weights"): torch.float16,
    ("touches", "labels"): torch.int8,
}
_SELECTED_KEY = "selected_tables"  # take() -> compress(), never written


def encode(state: dict, field: nn.Module, optimizer: torch.optim.Optimizer, storage: str) -> dict:
    """`state` (an OnlineMapper.state_dict() of `field` trained by `optimizer`) with every
    large table and its moments packed; the result loads back through `decode`."""
    return compress(take(state, field, optimizer, storage))


def prepare(field: nn.Module) -> None:
    """Draw `field`'s initial tables now, on the thread that owns torch's random stream, as
    `take`'s first call would: at the paper's table that is seconds, better spent before a
    run's clock starts than at its first checkpoint."""
    initial_tables(field, _large_tables(field))


def take(state: dict, field: nn.Module, optimizer: torch.optim.Optimizer, storage: str) -> dict:
    """The first half of `encode`, on the thread that trains the field: `state` copied
    (the large tables only in their updated rows, as `_pack` stores them), with every
    decision that reads the live field made. `compress` may then run on another thread
    while training goes on: it reads nothing the optimiser writes. The rows are selected on
    the field's device, so only the updated ones cross to the CPU here."""
    if storage not in STORAGES:
        raise ValueError(f"checkpoint storage {storage!r}: use one of {STORAGES}")
    tables = _table_parameters(field, optimizer, state["optimizer"]["state"])
    if not tables:
        return copy.deepcopy(state)
    # The first draw forks torch's global random stream: it must run here, not in a worker.
    init = initial_tables(field, _large_tables(field))
    updated = {name: _updated_rows(state["optimizer"]["state"][i]) for name, i in tables.items()}
    replayed = {
        name: init is not None and _matches_init(state["field"][name], init[name], updated[name])
        for name in tables
    }
    if storage == "auto":
        storage = (
            "exact"
            if _exact_bytes(state, tables, updated, replayed) <= EXACT_LIMIT_BYTES
            else "compact"
        )
    packed_field, packed_optimizer = dict(state["field"]), _copy_optimizer(state["optimizer"])
    selected = {}
    for name, index in tables.items():
        table = packed_field.pop(name)
        moments = packed_optimizer["state"][index]
        initial = init[name] if replayed[name] else None
        selected[name] = _select(table, moments, updated[name], initial, storage)
        selected[name]["param_index"] = index
        for key in ("moments", "exp_avg", "exp_avg_sq"):
            moments.pop(key, None)
    rng = init_rng_state(field) if any(replayed.values()) else None
    rest = copy.deepcopy({**state, "field": packed_field, "optimizer": packed_optimizer})
    return {**rest, _SELECTED_KEY: selected, INIT_KEY: rng}


def compress(taken: dict) -> dict:
    """The second half of `encode`: pack the rows `take` selected (the costly part)."""
    if _SELECTED_KEY not in taken:
        return taken
    rest = {k: v for k, v in taken.items() if k != _SELECTED_KEY}
    if any(e["storage"] == "compact" for e in taken[_SELECTED_KEY].values()):
        rest = _narrow_memory(rest)
    return {**rest, PACKED_KEY: {n: _pack(e) for n, e in taken[_SELECTED_KEY].items()}}


def _narrow_memory(state: dict) -> dict:
    """`state` with the memory's lists in _NARROWED in their narrow dtypes (new lists and
    dicts: the taken copy's own tensors are not changed in place)."""
    state, widths = dict(state), {}
    for (part, key), dtype in _NARROWED.items():
        tensors = (state.get(part) or {}).get(key)
        if not tensors or not _fits(tensors, dtype):
            continue
        widths[f"{part}/{key}"] = str(tensors[0].dtype).removeprefix("torch.")
        state[part] = {**state[part], key: [t.to(dtype) for t in tensors]}
    return {**state, NARROWED_KEY: widths}


def _fits(tensors: list[Tensor], dtype: torch.dtype) -> bool:
    """Integers narrow only where every value fits (labels are never rounded)."""
    if dtype.is_floating_point:
        return True
    info = torch.iinfo(dtype)
    return all(
        t.numel() == 0 or info.min <= int(t.min()) <= int(t.max()) <= info.max for t in tensors
    )


def _widen_memory(state: dict) -> dict:
    """The memory's narrowed lists back in the dtypes they were saved from."""
    widths = state.get(NARROWED_KEY) or {}
    state = {k: v for k, v in state.items() if k != NARROWED_KEY}
    for name, dtype in widths.items():
        part, key = name.split("/")
        wide = getattr(torch, dtype)
        state[part] = {**state[part], key: [t.to(wide) for t in state[part][key]]}
    return state


def decode(state: dict, field: nn.Module, source: str) -> dict:
    """The OnlineMapper.state_dict() that `encode` packed (`state` unchanged when nothing
    was); `field` is the one it will load into (built like the saved one); `source` names
    the checkpoint in the warning given when its initial rows do not replay exactly."""
    state = _widen_memory(state)
    packed = state.get(PACKED_KEY)
    if not packed:
        return state
    rng_state = state.get(INIT_KEY)
    init = initial_state(field, rng_state) if rng_state is not None else None
    full_field, full_optimizer = dict(state["field"]), _copy_optimizer(state["optimizer"])
    for name, entry in packed.items():
        table, moments = _unpack(entry, None if init is None else init.get(name), name, source)
        full_field[name] = table
        full_optimizer["state"][entry["param_index"]].update(moments)
    rest = {k: v for k, v in state.items() if k not in (PACKED_KEY, INIT_KEY)}
    return {**rest, "field": full_field, "optimizer": full_optimizer}


def _table_parameters(field: nn.Module, optimizer, opt_state: dict) -> dict[str, int]:
    """Field state_dict key -> optimiser state index of each large table with moments."""
    names = {id(p): name for name, p in field.named_parameters()}
    ordered = [p for group in optimizer.param_groups for p in group["params"]]
    tables = {}
    for index, p in enumerate(ordered):
        state = opt_state.get(index, {})
        has_moments = "moments" in state or "exp_avg_sq" in state
        if has_moments and _is_table(p) and id(p) in names:
            tables[names[id(p)]] = index
    return tables


def _is_table(p: Tensor) -> bool:
    """A parameter packed once it has moments: a hash table, not an MLP's weight."""
    return p.ndim >= 2 and p.shape[0] >= MIN_PACKED_ROWS


def _large_tables(field: nn.Module) -> list[str]:
    """Names of the field's tables (`_is_table`), with moments yet or not: their initial
    values are kept together."""
    return [name for name, p in field.named_parameters() if _is_table(p)]


def _copy_optimizer(optimizer_state: dict) -> dict:
    """A copy deep enough to drop or replace per-parameter state entries."""
    states = {k: dict(v) for k, v in optimizer_state["state"].items()}
    return {**optimizer_state, "state": states}


def _moments(state: dict) -> tuple[Tensor, Tensor]:
    """(m, v) of one parameter, whichever of FieldAdam's layouts it uses (fields/optim.py)."""
    if "moments" in state:
        return state["moments"][:, 0], state["moments"][:, 1]
    return state["exp_avg"], state["exp_avg_sq"]


def _updated_rows(state: dict) -> Tensor:
    """(rows,) bool, on the moments' device: rows with any non-zero moment (never updated
    otherwise)."""
    if "moments" in state:
        # A row's moments as 64-bit words: a row is updated when any bit is set (a -0.0
        # moment counts too: such a row is stored exactly, which restores it as it is).
        pair = state["moments"]
        words = pair.reshape(pair.shape[0], -1).view(torch.int64)
        return (words != 0).any(dim=1)
    m, v = _moments(state)
    return ((m != 0) | (v != 0)).reshape(m.shape[0], -1).any(dim=1)


def _matches_init(table: Tensor, init: Tensor, updated: Tensor) -> bool:
    """Whether the rows never updated still hold exactly their initial values (all three
    on the field's device)."""
    if init.shape != table.shape:
        return False
    # Whole-table comparison, then the mask: a boolean row selection of a 2^24-row table
    # took over 10 s of the training thread; this reads each table once.
    differs = (table.detach() != init).reshape(table.shape[0], -1).any(dim=1)
    return not bool((differs & ~updated).any())


def _exact_bytes(state: dict, tables: dict, updated: dict, replayed: dict) -> int:
    total = 0
    for name in tables:
        table = state["field"][name]
        row_bytes = table[0].numel() * 4
        rows = int(torch.count_nonzero(updated[name]))  # a bool sum widens every element
        kept = rows if replayed[name] else table.shape[0]
        total += rows * row_bytes * 2 + kept * row_bytes  # moments + table
    return total


def _digest(rows: Tensor) -> str:
    # The array's own buffer: tobytes() would copy it first (a GB at the paper's table).
    return hashlib.sha256(memoryview(rows.contiguous().numpy()).cast("B")).hexdigest()[:16]


def _select(
    table: Tensor, moments: dict, updated: Tensor, initial: Tensor | None, storage: str
) -> dict:
    """Copies, on the CPU, of what `_pack` stores of one table: its updated rows and their
    moments, and its other rows, or, where they still hold their `initial` values, only
    what `compress` needs to hash those (the initial table is never trained: it may be read
    from another thread)."""
    table = table.detach()
    # Row gathers on the table's device (each row moved as one word, fields/row_ops.py),
    # not boolean masks: these run on millions of rows between two optimiser steps.
    rows = updated.nonzero().squeeze(1)
    if "moments" in moments:  # one copy of both moments, then the halves
        pair = gather_rows(moments["moments"], rows).cpu()
        m, v = pair[:, 0], pair[:, 1]
    else:
        m, v = (t[updated].cpu() for t in _moments(moments))
    rest = None
    if initial is None:
        rest = gather_rows(table, (~updated).nonzero().squeeze(1)).cpu()
    return {
        "storage": storage,
        "shape": list(table.shape),
        "updated": updated.cpu(),
        "layout": "moments" if "moments" in moments else "exp_avg",
        "initial": initial,
        "untouched": rest,
        "table": gather_rows(table, rows).cpu(),
        "m": m,
        "v": v,
    }


def _untouched_digest(selected: dict) -> str:
    """The digest of the rows never updated: of their stored copy, else of their initial
    values (equal to them: `take` checked)."""
    if selected["untouched"] is not None:
        return _digest(selected["untouched"])
    initial = selected["initial"]
    other = (~selected["updated"]).nonzero().squeeze(1).to(initial.device)
    return _digest(gather_rows(initial, other).cpu())


def _pack(selected: dict) -> dict:
    """One table's entry as the checkpoint stores it (module docstring)."""
    storage, m, v = selected["storage"], selected["m"], selected["v"]
    rest = selected["untouched"]
    entry = {
        **{k: selected[k] for k in ("storage", "shape", "layout", "param_index")},
        "untouched_digest": _untouched_digest(selected),
        "updated": pack_planes(torch.from_numpy(np.packbits(selected["updated"].numpy()))),
        "untouched": None if rest is None else _narrow(rest, storage),
        "table": _narrow(selected["table"], storage),
    }
    if storage == "exact":
        entry.update({"m": m, "v": v})
    else:
        codes = quantise_moments(m, v)
        for key in ("ratio_codes", "scale_codes"):
            codes[key] = pack_planes(codes[key])
        entry.update(codes)
    return entry


def _narrow(values: Tensor, storage: str) -> Tensor | dict:
    """exact: float32 as it is; compact: float16 where every value fits (else float32),
    as deflated byte planes."""
    if storage == "exact":
        return values.float()
    half = values.half()
    return pack_planes(half if bool(torch.isfinite(half).all()) else values.float())


def _widen(stored: Tensor | dict) -> Tensor:
    """float32 values from `_narrow`'s either form."""
    return (unpack_planes(stored) if isinstance(stored, dict) else stored).float()


def _unpack(entry: dict, init: Tensor | None, name: str, source: str) -> tuple[Tensor, dict]:
    shape = entry["shape"]
    bits = np.unpackbits(unpack_planes(entry["updated"]).numpy(), count=shape[0]).astype(bool)
    updated = torch.from_numpy(bits)
    table = torch.empty(shape, dtype=torch.float32)
    table[updated] = _widen(entry["table"])
    if entry["untouched"] is not None:
        table[~updated] = _widen(entry["untouched"])
    elif init is None:
        raise ValueError(
            f"{source}: the never-updated rows of {name} are rebuilt from the field's "
            "initialisation; build the field with mapping.field_init.build_field to load it"
        )
    else:
        table[~updated] = init[~updated]
        if _digest(table[~updated]) != entry["untouched_digest"]:
            warnings.warn(
                f"{source}: the never-updated rows of {name} were drawn again but differ from "
                "the saved run's (its field initialisation changed); they hold a fresh draw",
                stacklevel=2,
            )
    if entry["storage"] == "exact":
        m, v = entry["m"].float(), entry["v"].float()
    else:
        m, v = dequantise_moments(entry)
    full_m, full_v = torch.zeros(shape), torch.zeros(shape)
    full_m[updated], full_v[updated] = m, v
    if entry["layout"] == "moments":
        return table, {"moments": torch.stack([full_m, full_v], dim=1)}
    return table, {"exp_avg": full_m, "exp_avg_sq": full_v}


def quantise_moments(m: Tensor, v: Tensor) -> dict:
    """8-bit codes of Adam's (m, v): log2(sqrt v) on 254 levels between its smallest and
    largest value (code 0: v = 0), and m / sqrt(v) on 255 levels symmetric about 0.
    In-place arithmetic on whole tensors (no masked copies): these run on millions of rows."""
    s = v.float().sqrt()
    zero = s == 0
    ratio = torch.div(m.float(), s.clamp(min=torch.finfo(torch.float32).tiny))  # m untouched
    ratio.masked_fill_(zero, 0.0)
    ratio_step = float(ratio.abs().max()) / 127 if ratio.numel() else 0.0
    ratio_codes = ratio.div_(ratio_step or 1.0).round_().clamp_(-127, 127).to(torch.int8)
    log_s = s.log2_()  # -inf where v = 0
    high = float(log_s.max()) if log_s.numel() else 0.0
    smallest = float(log_s.masked_fill(zero, float("inf")).min()) if log_s.numel() else 0.0
    # 64 octaves at most, so one tiny outlier cannot coarsen every other value's code.
    low = max(smallest, high - 64.0) if smallest != float("inf") else high
    log_step = (high - low) / 254 or 1.0
    codes = log_s.clamp_(min=low).sub_(low).div_(log_step).round_().add_(1.0)
    scale_codes = codes.to(torch.uint8).masked_fill_(zero, 0)
    return {
        "ratio_codes": ratio_codes,
        "ratio_step": ratio_step,
        "scale_codes": scale_codes,
        "log_low": low,
        "log_step": log_step,
    }


def dequantise_moments(entry: dict) -> tuple[Tensor, Tensor]:
    """(m, v) float32 from `quantise_moments`' codes (as they are or as byte planes)."""
    codes, ratio_codes = entry["scale_codes"], entry["ratio_codes"]
    if isinstance(codes, dict):
        codes, ratio_codes = unpack_planes(codes), unpack_planes(ratio_codes)
    s = torch.where(
        codes > 0,
        torch.exp2(entry["log_low"] + (codes.float() - 1.0) * entry["log_step"]),
        0.0,
    )
    m = ratio_codes.float() * entry["ratio_step"] * s
    return m, s * s
