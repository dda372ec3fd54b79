"""Schema for task=train_tactile_depth (the learned tactile depth network, source=net)."""

from __future__ import annotations

from dataclasses import dataclass, field

from neuralfeels_sem.configs.object import TACTILE_DATA_OBJECTS
from neuralfeels_sem.configs.root import TaskConfig
from neuralfeels_sem.configs.sensor_sim import _check_firmness
from neuralfeels_sem.core.digit import MAX_PENETRATION_M
from neuralfeels_sem.core.hand import FINGERS


@dataclass
class TrainTactileDepthTaskConfig(TaskConfig):
    """Renders presses in the simulator, trains the network, scores it on a held-out set
    rendered with `held_out_seed` over backgrounds it never saw."""

    train_samples: int = 2000
    held_out_samples: int = 400
    seed: int = 0  # the yaml sets ${seed}
    held_out_seed: int = 1000  # presses, textures and noise of the held-out set
    # Presses (sim/tactile_depth_collection.py).
    sensors: list[str] = field(default_factory=lambda: list(FINGERS))
    library_objects: list[str] = field(default_factory=lambda: list(TACTILE_DATA_OBJECTS))
    firmness_mm: dict[str, float] = field(
        default_factory=lambda: {"index": 1.5, "middle": 1.5, "ring": 1.5, "thumb": 0.7}
    )
    firmness_spread: float = 0.35  # relative std of the press around a finger's firmness
    uniform_press_fraction: float = 0.5  # presses drawn uniformly in [min_press_mm, 95 % of max]
    min_press_mm: float = 0.1
    miss_fraction: float = 0.1  # presses stopping up to max_gap_mm short of the gel
    max_gap_mm: float = 1.0
    max_tilt_deg: float = 15.0
    edge_press_fraction: float = 0.2
    edge_tilt_deg: list[float] = field(default_factory=lambda: [15.0, 40.0])
    texture_scale: float = 1.0
    # Backgrounds: procedural seeds 0..n-1 for training (sensor=sim's fingers use seed +
    # finger index, so the rig's own are among them), n_held_out others from seed 10000;
    # real empty frames: auto = ../shared/data/digit_real/backgrounds when present, null =
    # none, or a folder. Every real_held_out_every-th real frame is kept for the held-out set.
    procedural_backgrounds: int = 32
    held_out_procedural_backgrounds: int = 8
    real_backgrounds: str | None = "auto"
    real_held_out_every: int = 5
    # Network and training (perception/tactile_depth_net).
    width: int = 16
    input_size: list[int] = field(default_factory=lambda: [160, 120])  # rows, cols
    epochs: int = 10
    batch_size: int = 16
    lr: float = 3e-3
    depth_weight: float = 1.0
    max_noise_std: float = 4.0  # grey levels
    max_gain_drift: float = 0.03
    max_offset_drift: float = 4.0  # grey levels
    export_fp16: bool = False  # store tactile_depth.pt in half precision (the shipped asset)

    def __post_init__(self) -> None:
        for name in ("train_samples", "held_out_samples", "epochs", "procedural_backgrounds"):
            if getattr(self, name) < 1:
                raise ValueError(f"task.{name}={getattr(self, name)} must be >= 1")
        if self.batch_size < 2:
            raise ValueError(f"task.batch_size={self.batch_size} must be >= 2 (BatchNorm)")
        if self.held_out_procedural_backgrounds < 1 or self.real_held_out_every < 2:
            raise ValueError(
                "task.held_out_procedural_backgrounds must be >= 1 and task.real_held_out_every >= 2"
            )
        if not self.sensors or any(f not in FINGERS for f in self.sensors):
            raise ValueError(f"task.sensors={self.sensors} must be a non-empty subset of {FINGERS}")
        _check_firmness("task.firmness_mm", self.firmness_mm)
        self._check_fractions()
        top_mm = MAX_PENETRATION_M * 1000 * 0.95
        if not 0.0 < self.min_press_mm < top_mm:
            raise ValueError(f"task.min_press_mm={self.min_press_mm} must be in (0, {top_mm})")
        if self.max_gap_mm < 0 or self.texture_scale < 0 or not 0 <= self.max_tilt_deg < 60:
            raise ValueError(
                "task.max_gap_mm and task.texture_scale must be >= 0, task.max_tilt_deg in [0, 60)"
            )
        if (
            len(self.edge_tilt_deg) != 2
            or not 0 < self.edge_tilt_deg[0] <= self.edge_tilt_deg[1] < 80
        ):
            raise ValueError(
                f"task.edge_tilt_deg={self.edge_tilt_deg} must be [low, high] in (0, 80)"
            )
        if self.width < 4 or len(self.input_size) != 2 or min(self.input_size) < 32:
            raise ValueError(
                f"task.width={self.width} must be >= 4 and task.input_size={self.input_size} "
                "[rows, cols] both >= 32"
            )
        if self.lr <= 0 or self.depth_weight < 0:
            raise ValueError(f"task.lr={self.lr} must be > 0, task.depth_weight >= 0")
        if min(self.max_noise_std, self.max_gain_drift, self.max_offset_drift) < 0:
            raise ValueError("task.max_noise_std, max_gain_drift and max_offset_drift must be >= 0")

    def _check_fractions(self) -> None:
        for name in (
            "firmness_spread",
            "uniform_press_fraction",
            "miss_fraction",
            "edge_press_fraction",
        ):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"task.{name}={getattr(self, name)} must be in [0, 1]")


def register(cs) -> None:
    cs.store(group="schema/task", name="train_tactile_depth", node=TrainTactileDepthTaskConfig)
