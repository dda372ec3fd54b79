"""The online mapper: turns incoming Frames into optimiser steps on a semantic neural field.

Per frame: camera and tactile points go to the object frame (with the given pose, else
the frame's `world_T_object`; frame_points.py), the camera points become a keyframe and
every touch joins the replay buffer with its label when the classifier's label is usable
(memory.py, touch_memory.py, label_vote.py), then `steps_per_frame` optimiser steps run
(`warmup_steps` on the first frame with data). Each step draws a batch from memory
(batch.py, sampling.py, space_prior.py) and minimises the weighted losses (objective.py,
losses.py). Counters: bookkeeping.py; random states for exact resume: rng_state.py.

MapperConfig holds every setting and its only default; conf/mapping/online.yaml adds only
what the schema cannot know (the class count and the seed).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from neuralfeels_sem.core.errors import ConfigError, NoDataError, NumericalError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.fields.material_support import current_support
from neuralfeels_sem.mapping.batch import MATERIAL_SAMPLINGS, BatchSampler, per_keyframe_losses
from neuralfeels_sem.mapping.bookkeeping import TrainingLog
from neuralfeels_sem.mapping.frame_points import CAMERA_MASKS, PointExtractor
from neuralfeels_sem.mapping.label_vote import LabelVote
from neuralfeels_sem.mapping.mapper_checks import check_counts, check_lengths_and_weights
from neuralfeels_sem.mapping.memory import MapMemory
from neuralfeels_sem.mapping.objective import TERMS, MapperObjective
from neuralfeels_sem.mapping.press_fusion import PressFusion
from neuralfeels_sem.mapping.rng_state import capture_rng, restore_rng
from neuralfeels_sem.mapping.step_policy import STEPS_POLICIES, steps_for, surprise
from neuralfeels_sem.perception.camera_segmentation import SegmentationConfig
from neuralfeels_sem.perception.tactile_depth import TactileDepth, TactileDepthConfig
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.utils.frozen import frozen_parameters

LOSS_KEYS = ("total", *TERMS, "points")


@dataclass
class MapperConfig:
    """`mapping.mapper`: OnlineMapper's settings (the command line's defaults)."""

    num_classes: int = len(DEFAULT_MATERIALS)  # conf: ${len:${materials}}; must match the field
    # 2: three (half as many steps again) mapped no better at the 20 s default, nor five
    # better than three (docs/field_and_mapper.md#steps-per-frame)
    steps_per_frame: int = 2
    # fixed: steps_per_frame on every frame; surprise: min_steps_per_frame up to
    # steps_per_frame by how much of the new frame the field does not explain yet
    # (mapping/step_policy.py). surprise takes about half the steps but maps the generated
    # development objects worse (docs/field_and_mapper.md#steps-per-frame).
    steps_policy: str = "fixed"
    min_steps_per_frame: int = 1
    warmup_steps: int = 50  # steps on the first frame with data
    camera_points_per_frame: int = 4096  # stored per camera keyframe
    tactile_points_per_touch: int = 128  # stored per touch (with replacement for small patches)
    camera_rays: int = 288  # per step, from the keyframe window
    tactile_rays: int = 96  # per step, from all touches
    band_samples: int = 5  # per ray, inside the truncation band
    free_samples: int = 4  # per ray, in free space
    material_points: int = 256  # per step, from all labelled touches
    # uniform: every labelled point alike; balanced: each material the touches name gets an
    # equal share of the draws, so a small insert's few points train as often as the
    # largest material's many (batch.py); tempered: a material's share grows with its point
    # count to material_temper_power (1 is uniform, 0 balanced). balanced over-extends the
    # rare materials; tempered maps the generated development objects 92.3 % mean-class
    # against 91.7 with uniform, the shipped ones 96.7 against 96.9 (both measured with
    # sensor.tactile.ignored_faces=generic; docs/field_and_mapper.md#steps-per-frame).
    material_sampling: str = "tempered"
    material_temper_power: float = 0.5
    # This share of the material draws goes to the labelled touches of the newest
    # material_recent_frames frames (uniform among their points), the rest as above: a new
    # touch is otherwise one of hundreds and the map takes seconds to show it. 0: off.
    material_recent_share: float = 0.0
    material_recent_frames: int = 10
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
    # An outside point's SDF must reach its distance outside the hull of observed points, up
    # to this (metres); 0: only its sign. 5 mm: no loose sheets outside the hull (yarn_ball),
    # no development run's F-score at 5 mm lower by more than 0.001 (space_prior.py).
    space_prior_margin: float = 0.005
    # Frames between rebuilds of the hull of observed points (and the tree the prior's
    # samples keep clear of them with), ~25 ms of the mapper's CPU each: every 5th frame
    # mapped the shipped objects as every frame did, within 0.5 points on each of 16
    # 30 s runs (docs/field_and_mapper.md#where-a-default-runs-time-goes).
    space_prior_hull_every: int = 5
    material_weight: float = 0.1
    # Beyond this (metres) from every trained touch point the map reads the nearest one's
    # label (fields/material_support.py); null: the material branch's extrapolation alone.
    fill_m: float | None = 0.01
    # A labelled touch contradicted by its neighbours (>= min_neighbours labelled touches
    # within radius metres, fewer than min_agreement of them with its label) is not used
    # for the material loss, nor one backed by fewer than min_support touches with its label
    # within support_radius (null: radius). Touches are counted as presses: a finger's
    # touches at most press_gap mapped frames apart are one (0: every frame). radius 0 = off.
    label_vote_radius: float = 0.01
    label_vote_min_neighbours: int = 3
    label_vote_min_agreement: float = 0.25
    label_vote_min_support: int = 1
    label_vote_press_gap: int = 2
    label_vote_support_radius: float | None = 0.04
    # A press whose own labelled frames name a label steadily (>= steady_frames of them,
    # at least half) backs that label without a neighbour (label_vote.steady_presses);
    # 0 = off. 3: on 29 development objects it keeps the one press that is all a small
    # part gets, at a small cost on the shipped objects (docs/field_and_mapper.md).
    label_vote_steady_frames: int = 3
    # A press ends where its finger has slid this far (metres) from the press's first touch
    # (label_vote.press_events); null: presses by time alone. 1 cm: a finger that slides
    # across a small part reads it in a press of its own, steady enough to back itself.
    label_vote_press_reach: float | None = 0.01
    # Press fusion (press_fusion.py): a touch the classifier abstained on takes the class
    # that the presses within fuse_radius metres read together (at least fuse_min_presses
    # presses, pooled probability >= fuse_confidence), at fuse_weight; fuse_edge: touches
    # abstained on at the sensor's edge too. fuse_radius 0 = off.
    fuse_radius: float = 0.0
    fuse_min_presses: int = 2
    fuse_confidence: float = 0.9
    fuse_weight: float = 1.0
    fuse_edge: bool = False
    window_recent: int = 4  # keyframes: the most recent ones in every window
    window_by_loss: int = 4  # plus older ones drawn by their last loss
    max_keyframes: int = 200
    # Camera points inside: segment (a segmentation from depth and the hand's model,
    # perception/camera_segmentation.py; what a real rig has), gt (the simulator's object
    # mask, an oracle) or none (every valid pixel: hand, table and background too).
    camera_mask: str = "segment"
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    seed: int = 0  # conf: ${seed}
    tactile_depth: TactileDepthConfig = field(default_factory=TactileDepthConfig)

    def __post_init__(self) -> None:
        if self.steps_policy not in STEPS_POLICIES:
            raise ValueError(
                f"mapping.mapper.steps_policy={self.steps_policy!r}: use one of {', '.join(STEPS_POLICIES)}"
            )
        if not 1 <= self.min_steps_per_frame <= self.steps_per_frame:
            raise ValueError(
                f"mapping.mapper.min_steps_per_frame={self.min_steps_per_frame} must be in "
                f"[1, steps_per_frame={self.steps_per_frame}]"
            )
        if self.material_sampling not in MATERIAL_SAMPLINGS:
            raise ValueError(
                f"mapping.mapper.material_sampling={self.material_sampling!r}: use one of "
                f"{', '.join(MATERIAL_SAMPLINGS)}"
            )
        if not 0.0 <= self.material_recent_share <= 1.0:
            raise ValueError(
                f"mapping.mapper.material_recent_share={self.material_recent_share} must be in [0, 1]"
            )
        if not 0.0 <= self.material_temper_power <= 1.0:
            raise ValueError(
                f"mapping.mapper.material_temper_power={self.material_temper_power} must be in [0, 1]"
            )
        if self.camera_mask not in CAMERA_MASKS:
            raise ValueError(
                f"mapping.mapper.camera_mask={self.camera_mask!r}: use one of {', '.join(CAMERA_MASKS)}"
            )
        check_counts(self)
        check_lengths_and_weights(self)
        if self.label_vote_support_radius is not None and self.label_vote_support_radius < 0:
            raise ValueError(
                f"mapping.mapper.label_vote_support_radius={self.label_vote_support_radius} "
                "must be >= 0 (or null: the vote radius)"
            )
        if not 0.0 < self.label_vote_min_agreement <= 1.0:
            raise ValueError(
                f"mapping.mapper.label_vote_min_agreement={self.label_vote_min_agreement} must be in (0, 1]"
            )
        PressFusion.from_config(self)  # checks the fuse_* settings
        LabelVote.from_config(self)  # checks label_vote_press_reach
        if self.fill_m is not None and self.fill_m <= 0:
            raise ValueError(f"mapping.mapper.fill_m={self.fill_m} must be > 0 or null")
        if self.max_keyframes <= self.window_recent:
            raise ValueError(
                f"mapping.mapper.max_keyframes={self.max_keyframes} must exceed window_recent ({self.window_recent})"
            )


class OnlineMapper:
    """Trains `field` online from Frames; see the module docstring for one frame's work.

    Pose sources (pose_source.py) use only `frame_points`, `sdf`, `has_surface` and
    `move_frame`.
    """

    def __init__(
        self,
        config: MapperConfig,
        field: nn.Module,
        optimizer_factory: Callable[..., torch.optim.Optimizer],
        device: str | torch.device,
        hand_model: object | None = None,
    ) -> None:
        if getattr(field, "num_classes", config.num_classes) != config.num_classes:
            raise ConfigError(
                f"the field has {field.num_classes} classes, mapping.mapper.num_classes="
                f"{config.num_classes}; both follow `materials` unless overridden"
            )
        self.config = config
        self.num_classes = config.num_classes
        self.device = torch.device(device)
        self.field = field.to(self.device)
        self.optimizer = optimizer_factory(self.field.parameters())
        # The mapper's own generator: sampling is repeatable and resumable bit for bit.
        self.generator = torch.Generator().manual_seed(int(config.seed))
        self.points = PointExtractor(
            config.camera_mask,
            TactileDepth(config.tactile_depth, self.device),
            config.segmentation,
            hand_model,
        )
        self.memory = MapMemory(
            config, field.bound, field.center.detach().cpu().numpy(), self.generator, self.device
        )
        self.sampler = BatchSampler(config, self.memory, self.generator, self.device)
        self.objective = MapperObjective(config, self.generator)
        self.log = TrainingLog()

    # ------------------------------------------------------------ for pose sources
    def frame_points(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        """Object-frame surface points per source: `camera` and each finger in contact."""
        return self.points(frame, world_T_object)

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        """The field's signed distance (metres) at object-frame points x (N, 3),
        differentiable with respect to x only: pose sources read the field, they do not
        train it (and the encoding then takes its fused point-gradient kernel on the CPU)."""
        with frozen_parameters(self.field):
            return self.field.sdf(x)

    def move_frame(self, frame_index: int, object_T_object: np.ndarray) -> int:
        """Re-place what one frame added to the map (its pose was refined): the number of
        keyframes and touches moved."""
        return self.memory.move_frame(frame_index, object_T_object)

    @property
    def has_surface(self) -> bool:
        """Whether the field has trained on data yet (its warm-up steps ran)."""
        return self.log.warmed_up

    # ------------------------------------------------------------------ ingestion
    def add_frame(
        self,
        frame: Frame,
        touch_labels: Mapping[str, TouchLabel] | None = None,
        world_T_object: np.ndarray | None = None,
        steps: int | None = None,
    ) -> dict[str, float]:
        """Ingest one frame, then run `steps` optimiser steps (None: as steps_policy says,
        the first time warmup_steps; a realtime stream passes steps_per_frame, since the
        world does not wait for a warm-up)."""
        pose = frame.world_T_object if world_T_object is None else world_T_object
        _check_finite_pose(pose, frame.index)
        every_pixel = self.memory.space_prior is not None
        points, pixels = self.points.extract(frame, pose, every_pixel)
        camera, tactile = self.memory.add(frame, points, pixels, pose, touch_labels or {})
        self.log.camera_points_total += camera
        self.log.tactile_points_total += tactile
        self.log.frames_seen += 1
        if not self.memory.has_data:
            return dict.fromkeys(LOSS_KEYS, 0.0)
        if steps is None:
            steps = self._policy_steps(points, touch_labels or {})
        self.log.warmed_up = True
        return self.optimize(steps)

    def add_touches(
        self,
        frame: Frame,
        touch_labels: Mapping[str, TouchLabel],
        world_T_object: np.ndarray,
        depths: dict[str, np.ndarray] | None = None,
    ) -> int:
        """Ingest only the touches of a frame not mapped itself (sensor.pace=realtime:
        pipeline/touch_frames.py), without optimiser steps; how many points were kept.
        `depths`: its contact depths when already read (PointExtractor.contact_depths)."""
        _check_finite_pose(world_T_object, frame.index)
        points = self.points.touch_points(frame, world_T_object, depths)
        _, tactile = self.memory.add(frame, points, None, world_T_object, touch_labels)
        self.log.tactile_points_total += tactile
        self._refresh_support()
        return tactile

    def _policy_steps(self, points: dict[str, np.ndarray], labels: Mapping[str, TouchLabel]) -> int:
        config = self.config
        if not self.log.warmed_up:
            return max(config.steps_per_frame, config.warmup_steps)
        if config.steps_policy == "fixed":
            return config.steps_per_frame
        share = surprise(self.field, points, labels, config.truncation, self.device)
        return steps_for(share, config.min_steps_per_frame, config.steps_per_frame)

    @property
    def trained_on(self) -> dict:
        """What the field actually learned from (docs/design.md: metrics.json `trained_on`)."""
        return self.log.trained_on(self.memory.touches)

    # ------------------------------------------------------------------ optimisation
    def optimize(self, steps: int) -> dict[str, float]:
        """Run `steps` optimiser steps on the stored data; mean of each loss over them."""
        if not self.memory.has_data:
            raise NoDataError(
                "the mapper has no camera or tactile points yet; feed frames with data first"
            )
        totals = dict.fromkeys(LOSS_KEYS, 0.0)
        for _ in tqdm(range(steps), desc="mapping", unit="step", leave=False, disable=steps < 100):
            for key, value in self.step().items():
                totals[key] += value
        self._refresh_support()
        return {k: v / max(steps, 1) for k, v in totals.items()}

    def _refresh_support(self) -> None:
        """Hand the field the labelled points it trains on, for the fill (fill_m)."""
        if self.config.fill_m is not None and hasattr(self.field, "support"):
            touch = self.memory.touches.tensors()
            self.field.support = current_support(
                self.field.support, touch["labelled_points"], touch["labelled_labels"],
                self.num_classes, self.config.fill_m,
            )  # fmt: skip

    def step(self) -> dict[str, float]:
        """One optimiser step on a fresh batch; returns its losses."""
        batch = self.sampler.sample()
        # One pass for geometry and material points: the hash grid dominates the cost.
        out = self.field(batch.x, material_from=len(batch.x) - len(batch.material_labels))
        losses, per_sample = self.objective.losses(self.field, batch, out)
        if batch.camera is not None:
            camera_loss = per_sample[: len(batch.camera.samples)].detach()
            self.memory.keyframes.update_losses(*per_keyframe_losses(batch.camera, camera_loss))
        total = self.objective.total(losses)
        if not torch.isfinite(total):
            bad = [k for k, v in losses.items() if not torch.isfinite(v)]
            raise NumericalError(
                f"mapper loss is not finite at step {self.log.steps} ({', '.join(bad) or 'total'}); "
                "lower mapping.optimizer.lr or check the input depth and poses"
            )
        self.optimizer.zero_grad(set_to_none=True)
        total.backward()
        self.optimizer.step()
        self.log.steps += 1
        eikonal = self.objective.eikonal_points if self.objective.uses_eikonal(batch) else 0
        result = {k: float(v.detach()) for k, v in losses.items()}
        result.update(total=float(total.detach()), points=float(len(batch.x) + eikonal))
        return result

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        """Everything needed to continue bit for bit (loads with torch.load(weights_only=True))."""
        return {
            "field": self.field.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            **self.memory.state_dict(),
            "counters": self.log.state_dict(),
            "rng": capture_rng(self.generator),
            "perception": self.points.state_dict(),
        }

    def load_state_dict(self, state: dict) -> None:
        self.field.load_state_dict(state["field"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.memory.load_state_dict(state)
        self.log.load_state_dict(state["counters"])
        restore_rng(state["rng"], self.generator)
        self.points.load_state_dict(state.get("perception"))
        self._refresh_support()


def _check_finite_pose(pose: np.ndarray, frame_index: int) -> None:
    if not np.isfinite(pose).all():
        raise NumericalError(
            f"the object pose for frame {frame_index} is not finite (NaN/inf); "
            "the pose source diverged: try mapping.pose=gt"
        )
