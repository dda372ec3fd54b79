"""The classifier's traced CPU model, kept on disk so that a process pays tracing once.

Tracing and freezing the model (model.trace_for_cpu) takes 1-3 s of CPU; loading the
saved TorchScript file takes about 0.1 s. The file lives under data/classifier_traced/
(generated, never committed), named by the checkpoint's content hash, the input size
and the torch version, so a retrained checkpoint or another torch traces anew. Only
files this code wrote are read there; a file that does not load is traced over.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable
from pathlib import Path

import torch
from torch import nn

from neuralfeels_sem.perception.classifier.model import trace_for_cpu, warm_up
from neuralfeels_sem.utils.atomic import atomic_path
from neuralfeels_sem.utils.paths import cache_dir, file_digest

log = logging.getLogger(__name__)


def cached_trace(
    source: Path, input_size: int, folded: Callable[[], nn.Module], cache: Path | None = None
) -> nn.Module:
    """The traced model of checkpoint file `source` from `cache` (default data/
    classifier_traced/), else `trace_for_cpu(folded())`, saved there for the next time."""
    path = (cache or cache_dir("classifier_traced")) / _name(source, input_size)
    if path.is_file():
        try:
            with warnings.catch_warnings():  # torch 2.13 marks TorchScript deprecated
                warnings.simplefilter("ignore", DeprecationWarning)
                traced = torch.jit.load(str(path), map_location="cpu")
            warm_up(traced, input_size)
            return traced
        except Exception as exc:  # noqa: BLE001 (a damaged cache file is traced over)
            log.warning("traced classifier cache %s unreadable (%s); tracing again", path, exc)
    model = trace_for_cpu(folded(), input_size)
    if isinstance(model, torch.jit.ScriptModule):
        _save(model, path)
    return model


def _name(source: Path, input_size: int) -> str:
    digest = file_digest(source)
    return f"{digest}_{input_size}px_torch{torch.__version__.replace('+', '-')}.pt"


def _save(model: torch.jit.ScriptModule, path: Path) -> None:
    """Write atomically (utils/atomic.py: test workers may race)."""
    try:
        with atomic_path(path) as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.jit.save(model, str(tmp))
    except OSError as exc:  # a read-only checkout: trace again next time
        log.warning("could not cache the traced classifier at %s (%s)", path, exc)
