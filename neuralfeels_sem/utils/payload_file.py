"""Shipped-model checkpoints as plain-typed torch files: written atomically, read without
unpickling anything but tensors and plain types (torch.load(weights_only=True)), refused
with one line when missing, unreadable or of another format."""

from __future__ import annotations

from pathlib import Path

import torch

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.utils.atomic import atomic_write


def stored_state(model: torch.nn.Module, fp16: bool) -> dict[str, torch.Tensor]:
    """`model`'s tensors detached on the CPU, floating ones in half precision when `fp16`
    (the shipped assets' storage)."""
    state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
    if fp16:
        state = {k: v.half() if v.is_floating_point() else v for k, v in state.items()}
    return state


def float_state(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """A stored state with its floating tensors in fp32, as a model is built from it."""
    return {k: v.float() if v.is_floating_point() else v for k, v in state.items()}


def save_payload(payload: dict, path: str | Path) -> Path:
    """torch.save `payload` at `path`, never leaving a half-written file behind."""
    path = Path(path)
    with atomic_write(path, "wb") as f:
        torch.save(payload, f)
    return path


def load_payload(path: str | Path, what: str, fmt: str, arch: str, remedy: str) -> dict:
    """The dict saved at `path` with `"format": fmt` and `"arch": arch`; `what` names the
    file kind in errors ("classifier checkpoint"), `remedy` says how to get a good one."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{what} {path} does not exist; {remedy}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise DataError(
            f"{what} {path} is not readable ({exc.__class__.__name__}); {remedy}"
        ) from exc
    if not isinstance(payload, dict) or payload.get("format") != fmt:
        raise DataError(f"{path} is not a SemanticFeels {what} (expected format {fmt})")
    if payload.get("arch") != arch:
        raise DataError(f"{what} {path} is a {payload.get('arch')}, expected {arch}")
    return payload
