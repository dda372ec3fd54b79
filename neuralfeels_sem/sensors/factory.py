"""Build the configured sensor backend the same way for every task."""

from __future__ import annotations

import functools
import logging
from collections.abc import Sequence

from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sensors.base import IndexedSensor, Sensor
from neuralfeels_sem.sensors.process_sensor import ProcessSensor

log = logging.getLogger(__name__)


def build_sensor(
    sensor_cfg: DictConfig,
    obj: MaterialObject | None,
    class_names: Sequence[str],
    own_process: bool = False,
    nice: int = 0,
) -> Sensor:
    """Instantiate `sensor_cfg`; a partial sensor (sim, real) is completed with the object and
    classes. `own_process` (mapping.acquire_process): a sensor that makes frames by index
    (sensor=sim) runs in a child process (sensors/process_sensor.py), `nice` added to that
    process's nice value; a streaming one (a rig, a replay) stays in this process."""
    sensor = instantiate(sensor_cfg)
    if isinstance(sensor, functools.partial):
        sensor = sensor(obj=obj, class_names=list(class_names))
    if not isinstance(sensor, Sensor):
        raise TypeError(f"sensor config built {type(sensor).__name__}, not a Sensor")
    if not own_process:
        return sensor
    if not isinstance(sensor, IndexedSensor):
        # A rig's devices belong to the process that opened them; a replay streams files.
        log.info("sensor=%s streams: it runs in the mapping process", sensor_cfg.get("name"))
        return sensor
    # The child rebuilds it from plain values: a resolved config, the object, the classes.
    plain = OmegaConf.to_container(sensor_cfg, resolve=True)
    return ProcessSensor(functools.partial(_from_plain, plain, obj, list(class_names)), nice)


def _from_plain(plain: dict, obj: MaterialObject | None, class_names: list[str]) -> Sensor:
    return build_sensor(OmegaConf.create(plain), obj, class_names)
