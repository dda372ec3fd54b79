"""Build the configured sensor backend the same way for every task."""

from __future__ import annotations

import functools
from collections.abc import Sequence

from hydra.utils import instantiate
from omegaconf import DictConfig

from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sensors.base import Sensor


def build_sensor(
    sensor_cfg: DictConfig, obj: MaterialObject | None, class_names: Sequence[str]
) -> Sensor:
    """Instantiate `sensor_cfg`; a partial sensor (sim, real) is completed with the object and classes."""
    sensor = instantiate(sensor_cfg)
    if isinstance(sensor, functools.partial):
        sensor = sensor(obj=obj, class_names=list(class_names))
    if not isinstance(sensor, Sensor):
        raise TypeError(f"sensor config built {type(sensor).__name__}, not a Sensor")
    return sensor
