"""Schema for conf/mapping/: the online mapper, its optimiser, the pose source, checkpoints.

The dataclasses of the parts live beside the classes they configure and hold the only
defaults and range checks: MapperConfig in mapping/mapper.py (with TactileDepthConfig
from perception/tactile_depth.py), OptimizerConfig in fields/optim.py, TrackerConfig in
mapping/pose_tracker.py. The map task builds the mapper as
    OnlineMapper(to_config(MapperConfig, cfg.mapping.mapper), field, instantiate(cfg.mapping.optimizer), device)
(tasks/build.py build_mapper); the optimizer node is a `_partial_` FieldAdam factory.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from neuralfeels_sem.fields.optim import OptimizerConfig
from neuralfeels_sem.mapping.checkpoint_codec import STORAGES
from neuralfeels_sem.mapping.mapper import MapperConfig
from neuralfeels_sem.mapping.pose_source import POSE_SOURCES
from neuralfeels_sem.mapping.pose_tracker import TrackerConfig
from neuralfeels_sem.perception.tactile_depth import TactileDepthConfig
from neuralfeels_sem.pipeline.touch_advisor import TouchAdvisorConfig

__all__ = [
    "MapperConfig",
    "MappingConfig",
    "OptimizerConfig",
    "TactileDepthConfig",
    "TrackerConfig",
]


@dataclass
class MappingConfig:
    # gt: the frame's pose | track: SLAM | track_known_shape: against the GT mesh. A
    # PoseMode (mapping/pose_source.py); typed `str` because OmegaConf 2.3 rejects Literal.
    pose: str = "gt"
    # Frames between checkpoint.pt writes (0: only at the end; an interrupt writes one too):
    # 10 s of the sim rig's 10 Hz stream. Each write copies the updated rows on the mapper's
    # thread and packs ~100 MB of table and moments on another, about 1.5 CPU-seconds in
    # all on the 2-core CPU: at 50 frames, 7 % of a default run's CPU samples (py-spy).
    # One due while the last write runs is taken when it ends (CheckpointWriter.due).
    checkpoint_every: int = 100
    resume: str | None = None  # a checkpoint.pt to continue a killed run from
    # At sensor.pace=realtime: a frame due longer ago than this when the mapper could take
    # it is dropped (counted in metrics.json frames_dropped), so the map never trails the
    # world by more; room for one mapped frame plus its perception on the 2-core CPU under
    # load (docs/usage.md).
    max_lag_s: float = 2.0
    # At sensor.pace=realtime: the touches of up to this many frames overtaken before each
    # frame the mapper takes are still mapped (classified, placed and fused; no camera, no
    # optimiser steps; pipeline/touch_frames.py); 0: they are lost with their frames. Off
    # by default: in simulation on the 2-core CPU each costs about as much as a mapped
    # frame (its DIGITs rendered, classified, depth inferred), so 2 and 4 halved the frames
    # mapped for more touches and no better maps (docs/usage.md). On a rig whose DIGITs
    # stream anyway only the classification and depth are paid.
    overtaken_touch_frames: int = 0
    # Acquisition (rendering in sim, device reads on a rig) in a thread of its own, one
    # frame ahead of classification and perception (pipeline/producer.py); false: one
    # producer thread does both in turn. On the 2-core CPU, with the mapper's step as
    # cheap as the 2^16 table makes it, the default run's loop took 82.5-82.7 s against
    # 92.8-95.1 (the same map), and realtime runs mapped more frames (docs/usage.md).
    acquire_thread: bool = True
    # A sensor that makes frames by index (sensor=sim) runs in a process of its own
    # (sensors/process_sensor.py): the acquisition thread asks it for frames and waits on a
    # pipe, so the simulator's Python work no longer takes turns with perception and the
    # mapper on one interpreter lock. A streaming sensor (a rig, a replay) stays in the
    # mapping process. The default run, the same map either way: on an H200 at the 2^24
    # table a realtime factor of 0.87-1.11 against 0.75-0.88 (seeds 1 and 0); on the
    # 2-core CPU about the same (79-87 s of loop against 83-89; docs/field_and_mapper.md).
    acquire_process: bool = True
    # At sensor.pace=offline the mapper is the loop's critical path: the producer, scoring
    # and checkpoint threads add this to their nice value so that the mapper gets a core
    # first (utils/thread_priority.py; Linux; 0: an equal share). On the 2-core CPU the
    # default run's loop took 73.0 s against 75.5-80.8 (the same map; docs/usage.md).
    helper_nice: int = 10
    # How checkpoint.pt stores the hash tables (mapping/checkpoint_codec.py): auto = exact
    # float32 while that fits 40 MB, else compact (float16 table, 8-bit Adam moments);
    # exact = always bit-for-bit resumable; compact = always the small form.
    checkpoint_storage: str = "auto"
    optimizer: OptimizerConfig = field(default_factory=OptimizerConfig)
    mapper: MapperConfig = field(default_factory=MapperConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)  # read when pose tracks
    # where to touch next: advice for sensor.policy=active, suggestions on other rigs
    advisor: TouchAdvisorConfig = field(default_factory=TouchAdvisorConfig)

    def __post_init__(self) -> None:
        if self.pose not in POSE_SOURCES:
            raise ValueError(f"mapping.pose={self.pose} must be one of {POSE_SOURCES}")
        if not 0 <= self.helper_nice <= 19:
            raise ValueError(f"mapping.helper_nice={self.helper_nice} must be in 0..19 (0: off)")
        if self.checkpoint_every < 0:
            raise ValueError(f"mapping.checkpoint_every={self.checkpoint_every} must be >= 0")
        if self.checkpoint_storage not in STORAGES:
            raise ValueError(
                f"mapping.checkpoint_storage={self.checkpoint_storage} must be one of {STORAGES}"
            )
        if not 0.0 < self.max_lag_s <= 3600.0:
            raise ValueError(f"mapping.max_lag_s={self.max_lag_s} must be in (0, 3600] seconds")
        if self.overtaken_touch_frames < 0:
            raise ValueError(
                f"mapping.overtaken_touch_frames={self.overtaken_touch_frames} must be >= 0 "
                "(0: lost with their frames)"
            )


def register(cs) -> None:
    cs.store(group="schema/mapping", name="online", node=MappingConfig)
