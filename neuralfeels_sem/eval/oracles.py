"""Which simulator ground truth ("oracles") a mapping run used, from its composed config.

A real rig has none of them; `metrics.json["oracles"]` records them per run and the
results page lists them per source, so a sim figure says what it leaned on.
"""

from __future__ import annotations

from collections.abc import Mapping

# What each oracle is (names as metrics.json["oracles"]).
ORACLES = {
    "object_pose": "ground-truth object pose (mapping.pose=gt)",
    "camera_mask": "the simulator's camera object mask (mapping.mapper.camera_mask=gt)",
    "tactile_contact_depth": "the simulator's tactile contact depth (mapping.mapper.tactile_depth.source=gt)",
    "noise_free_depth": "noise-free camera depth (sensor.rgbd.depth_noise=none)",
    "material_labels": "ground-truth material labels (classifier=oracle)",
}


def oracles_used(config: Mapping) -> list[str]:
    """The oracles of a composed run config (a DictConfig or the plain dict of .hydra/config.yaml)."""
    sensor = config.get("sensor") or {}
    if sensor.get("name") != "sim":
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
