"""task=info: what this installation can do, for bug reports and set-up checks."""

from __future__ import annotations

import importlib
import json
import logging
import os
import platform

from omegaconf import DictConfig

from neuralfeels_sem.tasks.runner import output_dir

log = logging.getLogger(__name__)

OPTIONAL_MODULES = (
    "torch",
    "mujoco",
    "pyrender",
    "trimesh",
    "efficientnet_pytorch",
    "cv2",
    "can",
    "dynamixel_sdk",
    "pyrealsense2",
    "digit_interface",
    "tinycudann",
    "ray",
)


def _version(name: str) -> str | None:
    try:
        module = importlib.import_module(name)
    except Exception:  # an optional module may fail in many ways (missing .so, no CUDA)
        return None
    return str(getattr(module, "__version__", "installed"))


def collect_info() -> dict:
    import torch

    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "cuda_available": torch.cuda.is_available(),
        "cuda_device": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        "pyopengl_platform": os.environ.get("PYOPENGL_PLATFORM"),
        "modules": {name: _version(name) for name in OPTIONAL_MODULES},
    }
    return info


def run(cfg: DictConfig) -> dict:
    info = collect_info()
    path = output_dir() / "info.json"
    path.write_text(json.dumps(info, indent=2))
    for key, value in info.items():
        log.info("%s: %s", key, value)
    log.info("wrote %s", path)
    return info
