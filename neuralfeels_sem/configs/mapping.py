"""Schema for conf/mapping/: the online mapper, its optimiser, checkpoints and mesh export.

The task builds the mapper as
    instantiate(cfg.mapping.mapper)(field=field, optimizer_factory=instantiate(cfg.mapping.optimizer), device=device)
(both nodes are `_partial_`, so composing and instantiating the config stays cheap).
"""

from __future__ import annotations

from dataclasses import dataclass, field

POSE_SOURCES = ("gt", "track", "track_known_shape")
TACTILE_DEPTH_SOURCES = ("gt", "image")


@dataclass
class OptimizerConfig:
    """FieldAdam takes the hash grid's row-sparse gradients (model.encoding.sparse_grad)."""

    _target_: str = "neuralfeels_sem.fields.optim.FieldAdam"
    _partial_: bool = True
    lr: float = 3.0e-3
    betas: list[float] = field(default_factory=lambda: [0.9, 0.999])
    eps: float = 1.0e-8
    weight_decay: float = 0.0

    def __post_init__(self) -> None:
        if self.lr <= 0:
            raise ValueError(f"mapping.optimizer.lr={self.lr} must be > 0")
        if len(self.betas) != 2 or not all(0.0 <= b < 1.0 for b in self.betas):
            raise ValueError(
                f"mapping.optimizer.betas={list(self.betas)} must be two values in [0, 1)"
            )
        if self.eps < 0 or self.weight_decay < 0:
            raise ValueError(
                f"mapping.optimizer eps={self.eps} and weight_decay={self.weight_decay} must be >= 0"
            )


@dataclass
class TactileDepthConfig:
    _target_: str = "neuralfeels_sem.perception.tactile_depth.TactileDepth"
    source: str = "gt"  # gt: simulator depth | image: background-difference estimate (real sensors)
    contact_threshold: float = 12.0  # grey levels of change that count as contact
    full_press_intensity: float = 60.0  # grey levels of change at the deepest press
    blur_px: int = 7
    min_contact_px: int = 150

    def __post_init__(self) -> None:
        if self.source not in TACTILE_DEPTH_SOURCES:
            raise ValueError(
                f"mapping.mapper.tactile_depth.source={self.source} must be one of {TACTILE_DEPTH_SOURCES}"
            )
        if not 0 < self.contact_threshold < self.full_press_intensity:
            raise ValueError(
                f"mapping.mapper.tactile_depth needs 0 < contact_threshold ({self.contact_threshold}) "
                f"< full_press_intensity ({self.full_press_intensity})"
            )
        if self.blur_px < 1 or self.blur_px % 2 == 0:
            raise ValueError(
                f"mapping.mapper.tactile_depth.blur_px={self.blur_px} must be odd and >= 1"
            )


@dataclass
class MapperConfig:
    """Arguments of neuralfeels_sem.mapping.mapper.OnlineMapper (see its docstring)."""

    _target_: str = "neuralfeels_sem.mapping.mapper.OnlineMapper"
    _partial_: bool = True
    num_classes: int = 4
    steps_per_frame: int = 5
    warmup_steps: int = 50  # steps on the first frame with data
    camera_points_per_frame: int = 4096  # stored per camera keyframe
    tactile_points_per_touch: int = 128  # stored per touch (with replacement for small patches)
    camera_rays: int = 288  # per step, from the keyframe window
    tactile_rays: int = 96  # per step, from all touches
    band_samples: int = 5  # per ray, inside the truncation band
    free_samples: int = 4  # per ray, in free space
    material_points: int = 256  # per step, from all labelled touches
    truncation: float = 0.005  # metres
    camera_free_range: float = 0.05  # metres in front of the surface
    tactile_free_range: float = 0.01
    camera_weight: float = 1.0
    tactile_weight: float = 1.0
    sdf_weight: float = 1.0
    freespace_weight: float = 1.0
    eikonal_weight: float = 0.0
    eikonal_points: int = 256
    # Space-carving prior (mapping/space_prior.py): points per step in the cube, outside
    # where camera rays passed or outside the hull of observed points, solid elsewhere.
    space_prior_points: int = 512  # 0 = off
    space_prior_weight: float = 0.5
    space_prior_resolution: int = 64  # carving voxels per side
    material_weight: float = 0.1
    # A labelled touch contradicted by its neighbours (>= min_neighbours labelled touches
    # within radius metres, fewer than min_agreement of them with its label) is not used
    # for the material loss, nor one backed by fewer than min_support touches with its label
    # within support_radius (null: radius). Touches are counted as presses: a finger's
    # touches at most press_gap frames apart are one (0: every frame). radius 0 = off.
    label_vote_radius: float = 0.02
    label_vote_min_neighbours: int = 3
    label_vote_min_agreement: float = 0.25
    label_vote_min_support: int = 1
    label_vote_press_gap: int = 2
    label_vote_support_radius: float | None = 0.04
    window_recent: int = 4
    window_by_loss: int = 4
    max_keyframes: int = 200
    use_camera_mask: bool = True
    seed: int = 0
    tactile_depth: TactileDepthConfig = field(default_factory=TactileDepthConfig)

    def __post_init__(self) -> None:
        at_least = {
            "num_classes": 2,
            "steps_per_frame": 1,
            "warmup_steps": 0,
            "camera_points_per_frame": 1,
            "tactile_points_per_touch": 1,
            "camera_rays": 0,
            "tactile_rays": 0,
            "band_samples": 0,
            "free_samples": 0,
            "material_points": 0,
            "eikonal_points": 0,
            "space_prior_points": 0,
            "window_recent": 1,
            "window_by_loss": 0,
            "max_keyframes": 1,
            "label_vote_radius": 0.0,
            "label_vote_min_neighbours": 1,
            "label_vote_min_support": 0,
            "label_vote_press_gap": 0,
        }
        for name, low in at_least.items():
            if getattr(self, name) < low:
                raise ValueError(f"mapping.mapper.{name}={getattr(self, name)} must be >= {low}")
        if self.camera_rays + self.tactile_rays == 0:
            raise ValueError(
                "mapping.mapper.camera_rays and tactile_rays are both 0; at least one must be >= 1"
            )
        if self.truncation <= 0:
            raise ValueError(f"mapping.mapper.truncation={self.truncation} must be > 0")
        if self.label_vote_support_radius is not None and self.label_vote_support_radius < 0:
            raise ValueError(
                f"mapping.mapper.label_vote_support_radius={self.label_vote_support_radius} "
                "must be >= 0 (or null: the vote radius)"
            )
        if not 0.0 < self.label_vote_min_agreement <= 1.0:
            raise ValueError(
                f"mapping.mapper.label_vote_min_agreement={self.label_vote_min_agreement} must be in (0, 1]"
            )
        if self.space_prior_resolution < 8:
            raise ValueError(
                f"mapping.mapper.space_prior_resolution={self.space_prior_resolution} must be >= 8"
            )
        for name in ("camera_free_range", "tactile_free_range"):
            if getattr(self, name) < self.truncation:
                raise ValueError(
                    f"mapping.mapper.{name}={getattr(self, name)} must be >= truncation ({self.truncation})"
                )
        for name in (
            "camera_weight",
            "tactile_weight",
            "sdf_weight",
            "freespace_weight",
            "eikonal_weight",
            "space_prior_weight",
            "material_weight",
        ):
            if getattr(self, name) < 0:
                raise ValueError(f"mapping.mapper.{name}={getattr(self, name)} must be >= 0")
        if self.max_keyframes <= self.window_recent:
            raise ValueError(
                f"mapping.mapper.max_keyframes={self.max_keyframes} must exceed window_recent ({self.window_recent})"
            )


@dataclass
class TrackerConfig:
    """Arguments of neuralfeels_sem.mapping.pose_tracker.PoseTracker (mapping.pose=track*)."""

    _target_: str = "neuralfeels_sem.mapping.pose_tracker.PoseTracker"
    iterations: int = 15  # Levenberg-Marquardt iterations per frame
    robust_loss: str = "cauchy"  # huber | cauchy
    robust_scale: float = 0.001  # metres where the robust loss stops being quadratic
    min_points: int = 50  # fewer points: keep the predicted pose
    damping: float = 1.0e-3  # initial LM damping
    prior_weight: float = 0.01  # pull toward the constant-velocity prediction
    rotation_scale: float = 0.05  # metres per radian in the prior (about the object radius)
    max_step_m: float = 0.01  # largest translation of one LM step
    max_step_rad: float = 0.2  # largest rotation of one LM step
    max_motion_m: float = 0.03  # a result further from the prediction is rejected (diverged)
    max_points_per_source: int = 1000  # camera, and each finger
    source_weights: dict[str, float] = field(
        default_factory=lambda: {"camera": 1.0, "tactile": 1.0}
    )
    seed: int = 0

    def __post_init__(self) -> None:
        if self.iterations < 1 or self.min_points < 6 or self.max_points_per_source < 1:
            raise ValueError(
                f"mapping.tracker needs iterations >= 1 ({self.iterations}), min_points >= 6 "
                f"({self.min_points}) and max_points_per_source >= 1 ({self.max_points_per_source})"
            )
        if self.robust_loss not in ("huber", "cauchy"):
            raise ValueError(
                f"mapping.tracker.robust_loss={self.robust_loss} must be huber or cauchy"
            )
        if min(self.max_step_m, self.max_step_rad, self.max_motion_m) <= 0:
            raise ValueError(
                "mapping.tracker max_step_m, max_step_rad and max_motion_m must be > 0"
            )
        if min(self.robust_scale, self.damping, self.rotation_scale) <= 0 or self.prior_weight < 0:
            raise ValueError(
                "mapping.tracker robust_scale, damping and rotation_scale must be > 0, prior_weight >= 0"
            )
        if any(w < 0 for w in self.source_weights.values()):
            raise ValueError(
                f"mapping.tracker.source_weights={dict(self.source_weights)} must be >= 0"
            )


@dataclass
class MappingConfig:
    pose: str = "gt"  # gt: the frame's pose | track: SLAM | track_known_shape: against the GT mesh
    checkpoint_every: int = 25  # frames between checkpoint.pt writes (0: only at the end)
    resume: str | None = None  # a checkpoint.pt to continue a killed run from
    mesh_resolution: int = 128  # marching-cubes grid per axis over the model's bound
    optimizer: OptimizerConfig = field(default_factory=OptimizerConfig)
    mapper: MapperConfig = field(default_factory=MapperConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)

    def __post_init__(self) -> None:
        if self.pose not in POSE_SOURCES:
            raise ValueError(f"mapping.pose={self.pose} must be one of {POSE_SOURCES}")
        if self.checkpoint_every < 0:
            raise ValueError(f"mapping.checkpoint_every={self.checkpoint_every} must be >= 0")
        if not 16 <= self.mesh_resolution <= 1024:
            raise ValueError(
                f"mapping.mesh_resolution={self.mesh_resolution} must be in [16, 1024]"
            )


def register(cs) -> None:
    cs.store(group="schema/mapping", name="online", node=MappingConfig)
