"""Range checks of the classifier's settings: one place for its config and MaterialClassifier."""

from __future__ import annotations


def check_label_gates(
    min_confidence: float, max_edge_share: float, edge_px: int, edge_label_weight: float
) -> None:
    """The gates that decide whether a touch gets a label (perception/classifier/infer.py)."""
    if not 0.0 <= min_confidence <= 1.0:
        raise ValueError(f"classifier.min_confidence={min_confidence} must be in [0, 1]")
    if not 0.0 < max_edge_share <= 1.0:
        raise ValueError(f"classifier.max_edge_share={max_edge_share} must be in (0, 1]")
    if edge_px < 0:
        raise ValueError(f"classifier.edge_px={edge_px} must be >= 0")
    if not 0.0 <= edge_label_weight <= 1.0:
        raise ValueError(f"classifier.edge_label_weight={edge_label_weight} must be in [0, 1]")


EDGE_EXTENTS = ("whole", "patches", "centre")


def check_edge_extent(edge_extent: str) -> None:
    """How far a trusted edge imprint's label reaches (MaterialClassifier.classify)."""
    if edge_extent not in EDGE_EXTENTS:
        raise ValueError(
            f"classifier.edge_extent={edge_extent!r} must be one of {', '.join(EDGE_EXTENTS)}"
        )


def check_patch_reading(
    spacing_px: int, max_patches: int, probe: int, min_contact: float, disagree_confidence: float
) -> None:
    """The patch-reading settings (perception/classifier/patch_reader.py)."""
    if not 0 <= spacing_px <= 240:
        raise ValueError(f"classifier.patch_spacing_px={spacing_px} must be in 0..240 (0 = off)")
    if not 1 <= max_patches <= 64:
        raise ValueError(f"classifier.max_patches={max_patches} must be in 1..64")
    if not 0 <= probe <= 64:
        raise ValueError(f"classifier.patch_probe={probe} must be in 0..64 (0: read every patch)")
    if not 0.0 <= min_contact <= 1.0:
        raise ValueError(f"classifier.patch_min_contact={min_contact} must be in [0, 1]")
    if not 0.0 <= disagree_confidence <= 1.0:
        raise ValueError(
            f"classifier.patch_disagree_confidence={disagree_confidence} must be in [0, 1]"
        )
