"""The hand model a recording names, so a replay can segment its camera frames.

A recording stores its sensor's hand model (Sensor.hand_model()) as a class path and the
palm pose the model was built at; a replay rebuilds it from them. The class is looked up
by name, so replaying a sim recording needs the simulator's package installed but no
import of it here (sensors/real and sensors/replay never import the simulator).
"""

from __future__ import annotations

import logging

import numpy as np
from hydra.utils import get_class

from neuralfeels_sem.core.errors import DataError
from neuralfeels_sem.core.geometry import check_pose

log = logging.getLogger(__name__)


def hand_model_spec(model: object | None) -> dict | None:
    """{"class": dotted path, "world_T_palm": 4x4 list} of a hand model; None without one."""
    if model is None:
        return None
    palm = getattr(model, "world_T_palm", None)
    if palm is None:
        log.warning("hand model %s has no world_T_palm: not stored", type(model).__name__)
        return None
    return {
        "class": f"{type(model).__module__}.{type(model).__qualname__}",
        "world_T_palm": np.asarray(palm, np.float64).tolist(),
    }


def hand_model_from_spec(spec: dict | None, source: str) -> object | None:
    """The hand model `spec` names (None for None); `source` names the file for errors."""
    if spec is None:
        return None
    try:
        cls = get_class(str(spec["class"]))
        palm = np.asarray(spec["world_T_palm"], np.float64)
        check_pose(palm, "world_T_palm")
    except (KeyError, TypeError, ValueError, ImportError, AttributeError) as exc:
        raise DataError(f"{source}: hand_model {spec!r} cannot be rebuilt ({exc})") from None
    return cls(world_T_palm=palm)
