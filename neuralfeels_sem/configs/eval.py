"""Schema for conf/eval/: how often and how finely a run is scored (plain settings read by the task)."""

from __future__ import annotations

from dataclasses import dataclass, field

from neuralfeels_sem.eval.mesh_transfer import check_tolerance


@dataclass
class EvalConfig:
    # Score the material map every K processed frames (and always on the last frame).
    every_k_frames: int = 5
    # Area-uniform ground-truth surface samples in the regions of interest (3D matching %).
    num_surface_samples: int = 20000
    # Fixed views for the paper's image form of the matching percentage (and material_maps.png).
    image_views: int = 4
    image_size: int = 256
    image_elevation_deg: float = 30.0
    # F-score curve thresholds; F@5 mm is always reported as fscore_5mm.
    fscore_thresholds_mm: list[float] = field(
        default_factory=lambda: [float(t) for t in range(1, 21)]
    )
    # Points sampled on each mesh for F-score and Chamfer distance.
    shape_samples: int = 20000
    # Marching-cubes grid resolution (cells per axis) of the mesh extracted for evaluation.
    mesh_resolution: int = 128
    # Shape-aware matching (matching_mesh_pct): a ground-truth sample whose nearest point on
    # the extracted mesh is farther than this counts as wrong (metres).
    mesh_match_tolerance_m: float = 0.005
    seed: int = 0

    def __post_init__(self) -> None:
        if self.every_k_frames < 1:
            raise ValueError(f"eval.every_k_frames={self.every_k_frames} must be >= 1")
        if self.num_surface_samples < 100:
            raise ValueError(f"eval.num_surface_samples={self.num_surface_samples} must be >= 100")
        if self.image_views < 1:
            raise ValueError(f"eval.image_views={self.image_views} must be >= 1")
        if not 16 <= self.image_size <= 2048:
            raise ValueError(f"eval.image_size={self.image_size} must be in 16..2048")
        if not -89.0 <= self.image_elevation_deg <= 89.0:
            raise ValueError(
                f"eval.image_elevation_deg={self.image_elevation_deg} must be in -89..89"
            )
        if not self.fscore_thresholds_mm or any(t <= 0 for t in self.fscore_thresholds_mm):
            raise ValueError(
                f"eval.fscore_thresholds_mm={self.fscore_thresholds_mm} must be non-empty and > 0"
            )
        if self.shape_samples < 100:
            raise ValueError(f"eval.shape_samples={self.shape_samples} must be >= 100")
        if not 16 <= self.mesh_resolution <= 1024:
            raise ValueError(f"eval.mesh_resolution={self.mesh_resolution} must be in 16..1024")
        check_tolerance(self.mesh_match_tolerance_m)  # the check labels_from_mesh makes
        if self.seed < 0:
            raise ValueError(f"eval.seed={self.seed} must be >= 0")


def register(cs) -> None:
    cs.store(group="schema/eval", name="default", node=EvalConfig)
