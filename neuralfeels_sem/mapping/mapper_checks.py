"""MapperConfig's range checks (mapper.py): each a one-line ValueError naming the key."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig


def check_counts(config: MapperConfig) -> None:
    """Every count setting at or above its floor (one-line ValueErrors naming the key)."""
    at_least = {
        "num_classes": 2, "steps_per_frame": 1, "warmup_steps": 0,
        "camera_points_per_frame": 1, "tactile_points_per_touch": 1,
        "camera_rays": 0, "tactile_rays": 0, "band_samples": 0, "free_samples": 0,
        "material_points": 0, "eikonal_points": 0, "space_prior_points": 0,
        "space_prior_resolution": 8, "space_prior_hull_every": 1, "window_recent": 1,
        "window_by_loss": 0, "max_keyframes": 1, "label_vote_min_neighbours": 1,
        "label_vote_min_support": 0, "label_vote_press_gap": 0, "label_vote_steady_frames": 0,
        "material_recent_frames": 1,
    }  # fmt: skip
    for name, low in at_least.items():
        if getattr(config, name) < low:
            raise ValueError(f"mapping.mapper.{name}={getattr(config, name)} must be >= {low}")
    if config.camera_rays + config.tactile_rays == 0:
        raise ValueError(
            "mapping.mapper.camera_rays and tactile_rays are both 0; at least one must be >= 1"
        )


def check_lengths_and_weights(config: MapperConfig) -> None:
    """Lengths positive, free ranges beyond the truncation, weights non-negative."""
    if config.truncation <= 0:
        raise ValueError(f"mapping.mapper.truncation={config.truncation} must be > 0")
    for name in ("camera_free_range", "tactile_free_range"):
        if getattr(config, name) < config.truncation:
            raise ValueError(
                f"mapping.mapper.{name}={getattr(config, name)} must be >= truncation ({config.truncation})"
            )
    non_negative = (
        "camera_weight", "tactile_weight", "sdf_weight", "freespace_weight",
        "eikonal_weight", "space_prior_weight", "space_prior_margin", "material_weight",
        "label_vote_radius",
    )  # fmt: skip
    for name in non_negative:
        if getattr(config, name) < 0:
            raise ValueError(f"mapping.mapper.{name}={getattr(config, name)} must be >= 0")
