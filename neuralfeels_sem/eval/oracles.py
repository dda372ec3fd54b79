"""Which simulator ground truth ("oracles") a mapping run used, from its composed config.

A real rig has none of them; `metrics.json["oracles"]` records them per run and the
results page lists them per source, so a sim figure says what it leaned on.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from neuralfeels_sem.sensors.replay.recording_files import recorded_sensor_config

# What each oracle is (names as metrics.json["oracles"]).
ORACLES = {
    "object_pose": "ground-truth object pose (mapping.pose=gt)",
    "camera_mask": "the simulator's camera object mask (mapping.mapper.camera_mask=gt)",
    "tactile_contact_depth": "the simulator's tactile contact depth (mapping.mapper.tactile_depth.source=gt)",
    "noise_free_depth": "noise-free camera depth (sensor.rgbd.depth_noise=none)",
    "material_labels": "ground-truth material labels (classifier=oracle)",
}


# A replay of a recording of a replay ... is followed back this many recordings at most.
MAX_REPLAYS_BACK = 8


def oracles_used(config: Mapping) -> list[str]:
    """The oracles of a composed run config (a DictConfig or the plain dict of .hydra/config.yaml).

    A replay of a recording the simulator made leans on the simulator's ground truth as the
    simulated run would (its poses, masks and depths are the simulator's), judged with the
    sensor config it was recorded with; a rig, or a recording that does not say where it
    came from, has none.
    """
    sensor = simulated_sensor(config.get("sensor") or {})
    if sensor is None:
        return []
    mapping = config.get("mapping") or {}
    mapper = mapping.get("mapper") or {}
    rgbd = sensor.get("rgbd") or {}
    # Configs saved before camera_mask / depth_noise replaced use_camera_mask /
    # depth_noise_std still name their oracles (the results page reads stored runs).
    legacy_mask = "gt" if mapper.get("use_camera_mask") is True else None
    camera_mask = mapper.get("camera_mask", legacy_mask)
    legacy_noise = "none" if rgbd.get("depth_noise_std", 0.0) == 0.0 else "gaussian"
    noise_free = rgbd.get("depth_noise", legacy_noise) == "none"
    classifier = str((config.get("classifier") or {}).get("_target_", ""))
    used = {
        "object_pose": mapping.get("pose") == "gt",
        "camera_mask": camera_mask == "gt",
        "tactile_contact_depth": (mapper.get("tactile_depth") or {}).get("source") == "gt",
        "noise_free_depth": noise_free,
        "material_labels": classifier.endswith("OracleClassifier"),
    }
    return [name for name, on in used.items() if on]


def simulated_sensor(sensor: Mapping) -> Mapping | None:
    """The simulator's sensor config behind `sensor`: itself for sensor=sim; for a replay of a
    native recording, the sensor config the recording was made with, followed back through
    replays of replays; None for a rig, a FeelSight log or a recording without its config."""
    for _ in range(MAX_REPLAYS_BACK):
        if sensor.get("name") == "sim":
            return sensor
        native = sensor.get("format", "native") == "native"
        if sensor.get("name") != "replay" or not native or not sensor.get("recording"):
            return None
        sensor = recorded_sensor_config(Path(str(sensor.get("recording"))).expanduser())
        if sensor is None:
            return None
    return None
