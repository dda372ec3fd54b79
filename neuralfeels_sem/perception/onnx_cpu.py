"""CPU inference of the perception networks through ONNX Runtime (`cpu_runtime=onnxruntime`).

On this project's 2-core CPU (one thread, load 1-2) ONNX Runtime ran the classifier's
EfficientNet-B0 (112 px) in 5.8 ms a crop at batch 4 against 10.9 ms for the traced
TorchScript model, and the tactile depth network in 4.9 against 8.9 ms a frame: its
kernels fuse the convolutions with their activations and keep one layout throughout.
Outputs agree with torch's to float rounding (classifier logits within about 2e-4), not to
the bit, so `cpu_runtime=torch` remains for a bit-exact comparison with older runs.

The network is exported once (torch's TorchScript-based ONNX exporter, batch axis dynamic)
and kept under data/onnx/ (generated, never committed), named by the checkpoint's content
hash, the input shape and the torch version. Only files this code wrote are read there; a
file that does not load is exported over. An ONNX file is a protobuf graph, not a pickle.
"""

from __future__ import annotations

import contextlib
import io
import logging
import tempfile
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Literal, get_args

import numpy as np
import torch
from torch import nn

from neuralfeels_sem.core.errors import ConfigError
from neuralfeels_sem.utils.atomic import atomic_path
from neuralfeels_sem.utils.paths import cache_dir, file_digest

log = logging.getLogger(__name__)

CpuRuntime = Literal["onnxruntime", "torch"]
CPU_RUNTIMES = get_args(CpuRuntime)
OPSET = 17


def check_cpu_runtime(key: str, value: str) -> None:
    """One-line error for a `cpu_runtime` setting that is not a CpuRuntime."""
    if value not in CPU_RUNTIMES:
        raise ValueError(f"{key}={value!r} is unknown; use one of {CPU_RUNTIMES}")


class OnnxModule:
    """An ONNX Runtime session called like the torch module it was exported from: CPU
    float32 tensors in, a tensor (one output) or a tuple of tensors out."""

    training = False  # predict_probs skips eval() for a model already in eval mode

    def __init__(self, session, outputs: int) -> None:
        self.session = session
        self.input_name = session.get_inputs()[0].name
        self.outputs = outputs

    def __call__(self, x: torch.Tensor) -> torch.Tensor | tuple[torch.Tensor, ...]:
        feed = {self.input_name: np.ascontiguousarray(x.detach().cpu().float().numpy())}
        out = [torch.from_numpy(y) for y in self.session.run(None, feed)]
        return out[0] if self.outputs == 1 else tuple(out)


def onnx_module(
    source: Path,
    build: Callable[[], nn.Module],
    input_shape: Sequence[int],
    outputs: int = 1,
    cache: Path | None = None,
) -> OnnxModule:
    """The module of checkpoint file `source` (`build()`: in eval mode, on the CPU) as an
    ONNX Runtime session with torch's thread count, exported to `cache` (default data/onnx/)
    on first use. `input_shape` is one input without its batch axis: (3, H, W)."""
    ort = _import_onnxruntime()
    path = (cache or cache_dir("onnx")) / _name(source, input_shape)
    if path.is_file():
        try:
            return OnnxModule(_session(ort, path), outputs)
        except Exception as exc:  # noqa: BLE001 (a damaged cache file is exported over)
            log.warning("ONNX cache %s unreadable (%s); exporting again", path, exc)
    try:
        _export(build(), input_shape, outputs, path)
    except OSError as exc:  # a read-only checkout: export to a temporary file each time
        log.warning("could not cache the ONNX export at %s (%s)", path, exc)
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / path.name
            _export(build(), input_shape, outputs, path)
            return OnnxModule(_session(ort, path), outputs)
    return OnnxModule(_session(ort, path), outputs)


def _import_onnxruntime():
    try:
        import onnxruntime
    except ImportError as exc:
        raise ConfigError(
            "cpu_runtime=onnxruntime needs the onnxruntime and onnx packages "
            "(pip install onnxruntime onnx); or set cpu_runtime=torch"
        ) from exc
    return onnxruntime


def _session(ort, path: Path):
    options = ort.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()  # the run's `threads`
    options.inter_op_num_threads = 1
    # Waiting threads must not spin on a busy machine (utils/device.py: OpenMP's did).
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    options.log_severity_level = 3  # errors only
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def _name(source: Path, input_shape: Sequence[int]) -> str:
    digest = file_digest(source)
    shape = "x".join(str(int(s)) for s in input_shape)
    version = torch.__version__.replace("+", "-")
    return f"{source.stem}_{digest}_{shape}_torch{version}_opset{OPSET}.onnx"


def _export(model: nn.Module, input_shape: Sequence[int], outputs: int, path: Path) -> None:
    """Export with a dynamic batch axis, written atomically (utils/atomic.py)."""
    try:
        import onnx  # noqa: F401  (torch's exporter needs it)
    except ImportError as exc:
        raise ConfigError(
            "cpu_runtime=onnxruntime needs the onnx package to export the network "
            "(pip install onnx); or set cpu_runtime=torch"
        ) from exc
    names = [f"out{i}" for i in range(outputs)]
    axes = {name: {0: "batch"} for name in ["x", *names]}
    example = torch.zeros(2, *input_shape)
    # The TorchScript-based exporter warns that it is deprecated and prints its notes.
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with contextlib.redirect_stdout(io.StringIO()):
            torch.onnx.export(model, (example,), str(tmp), dynamo=False, input_names=["x"],
                              output_names=names, dynamic_axes=axes, opset_version=OPSET)  # fmt: skip
