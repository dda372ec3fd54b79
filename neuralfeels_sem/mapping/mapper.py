"""The online mapper: turns incoming Frames into optimiser steps on a semantic neural field.

Per frame: camera and tactile points go to the object frame (with the given pose, else
the frame's `world_T_object`), the camera points become a keyframe, every touch joins a
replay buffer (with its label when the classifier's label is usable), then
`steps_per_frame` optimiser steps run (`warmup_steps` on the first frame with data).
Each step draws rays from the keyframe window and from all touches, samples along them
(sampling.py) and minimises the truncated-SDF, free-space, space-prior (space_prior.py),
optional eikonal and material losses (losses.py).
"""

from __future__ import annotations

import random
from collections.abc import Callable, Mapping

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from neuralfeels_sem.errors import ConfigError, NoDataError, NumericalError
from neuralfeels_sem.mapping.keyframes import KeyframeBuffer, TouchBuffer
from neuralfeels_sem.mapping.losses import (
    batch_bound,
    eikonal_loss,
    freespace_loss,
    material_loss,
    space_prior_loss,
    truncated_sdf_loss,
)
from neuralfeels_sem.mapping.sampling import (
    RaySamples,
    random_indices,
    sample_along_rays,
    subsample,
)
from neuralfeels_sem.mapping.space_prior import SpaceCarvingPrior
from neuralfeels_sem.perception.pointcloud import (
    camera_points,
    sensor_origin_and_axis,
    tactile_points,
)
from neuralfeels_sem.perception.tactile_depth import TactileDepth
from neuralfeels_sem.perception.touch import TouchLabel
from neuralfeels_sem.sensors.frame import Frame

POSE_SOURCES = ("gt", "track", "track_known_shape")
LOSS_KEYS = ("total", "sdf", "freespace", "space", "eikonal", "material", "points")


def resolve_pose_source(pose: str) -> str:
    """Check `mapping.pose`: `gt`, `track` or `track_known_shape` (mapping/pose_source.py)."""
    if pose not in POSE_SOURCES:
        raise ConfigError(f"mapping.pose={pose!r} is unknown; use one of {POSE_SOURCES}")
    return pose


class OnlineMapper:
    """Trains `field` online from Frames; see the module docstring for one frame's work."""

    def __init__(
        self,
        field: nn.Module,
        optimizer_factory: Callable[..., torch.optim.Optimizer],
        num_classes: int,
        steps_per_frame: int = 5,
        warmup_steps: int = 50,
        camera_points_per_frame: int = 4096,
        tactile_points_per_touch: int = 128,
        camera_rays: int = 288,
        tactile_rays: int = 96,
        band_samples: int = 5,
        free_samples: int = 4,
        material_points: int = 256,
        truncation: float = 0.005,
        camera_free_range: float = 0.05,
        tactile_free_range: float = 0.01,
        camera_weight: float = 1.0,
        tactile_weight: float = 1.0,
        sdf_weight: float = 1.0,
        freespace_weight: float = 1.0,
        eikonal_weight: float = 0.0,
        eikonal_points: int = 256,
        space_prior_points: int = 0,
        space_prior_weight: float = 0.5,
        space_prior_resolution: int = 64,
        material_weight: float = 0.01,
        label_vote_radius: float = 0.0,
        label_vote_min_neighbours: int = 3,
        label_vote_min_agreement: float = 0.25,
        label_vote_min_support: int = 0,
        label_vote_press_gap: int = 0,
        label_vote_support_radius: float | None = None,
        window_recent: int = 4,
        window_by_loss: int = 4,
        max_keyframes: int = 200,
        tactile_depth: TactileDepth | None = None,
        use_camera_mask: bool = True,
        seed: int = 0,
        device: str | torch.device = "cpu",
    ) -> None:
        if num_classes < 2:
            raise ValueError(f"num_classes={num_classes} must be >= 2")
        positive = {
            "camera_points_per_frame": camera_points_per_frame,
            "tactile_points_per_touch": tactile_points_per_touch,
            "truncation": truncation,
        }
        for name, value in positive.items():
            if value <= 0:
                raise ValueError(f"{name}={value} must be > 0")
        counts = {
            "steps_per_frame": steps_per_frame,
            "warmup_steps": warmup_steps,
            "camera_rays": camera_rays,
            "tactile_rays": tactile_rays,
            "band_samples": band_samples,
            "free_samples": free_samples,
            "material_points": material_points,
            "eikonal_points": eikonal_points,
            "space_prior_points": space_prior_points,
        }
        for name, value in counts.items():
            if value < 0:
                raise ValueError(f"{name}={value} must be >= 0")
        self.device = torch.device(device)
        self.field = field.to(self.device)
        self.optimizer = optimizer_factory(self.field.parameters())
        self.num_classes = num_classes
        self.steps_per_frame = steps_per_frame
        self.warmup_steps = warmup_steps
        self.camera_points_per_frame = camera_points_per_frame
        self.tactile_points_per_touch = tactile_points_per_touch
        self.camera_rays = camera_rays
        self.tactile_rays = tactile_rays
        self.band_samples = band_samples
        self.free_samples = free_samples
        self.material_points = material_points
        self.truncation = float(truncation)
        self.camera_free_range = max(float(camera_free_range), self.truncation)
        self.tactile_free_range = max(float(tactile_free_range), self.truncation)
        self.camera_weight = camera_weight
        self.tactile_weight = tactile_weight
        self.sdf_weight = sdf_weight
        self.freespace_weight = freespace_weight
        self.eikonal_weight = eikonal_weight
        self.eikonal_points = eikonal_points
        self.space_prior_points = space_prior_points
        self.space_prior_weight = space_prior_weight
        self.space_prior = (
            SpaceCarvingPrior(
                float(field.bound),
                field.center.detach().cpu().numpy(),
                resolution=space_prior_resolution,
                seed=seed,
            )
            if space_prior_points > 0
            else None
        )
        self.material_weight = material_weight
        self.tactile_depth = tactile_depth or TactileDepth("gt")
        self.use_camera_mask = use_camera_mask
        self.keyframes = KeyframeBuffer(max_keyframes, window_recent, window_by_loss)
        if (
            label_vote_radius < 0
            or label_vote_min_neighbours < 1
            or min(label_vote_min_support, label_vote_press_gap) < 0
        ):
            raise ValueError(
                f"label_vote_radius={label_vote_radius} must be >= 0, "
                f"label_vote_min_neighbours={label_vote_min_neighbours} >= 1, "
                f"label_vote_min_support={label_vote_min_support} and "
                f"label_vote_press_gap={label_vote_press_gap} >= 0"
            )
        if label_vote_support_radius is not None and label_vote_support_radius < 0:
            raise ValueError(
                f"label_vote_support_radius={label_vote_support_radius} must be >= 0 (or None)"
            )
        if not 0.0 < label_vote_min_agreement <= 1.0:
            raise ValueError(
                f"label_vote_min_agreement={label_vote_min_agreement} must be in (0, 1]"
            )
        self.touches = TouchBuffer(
            self.device,
            label_vote_radius,
            label_vote_min_neighbours,
            label_vote_min_agreement,
            label_vote_min_support,
            label_vote_press_gap,
            label_vote_support_radius,
        )
        # The mapper's own generator: sampling is repeatable and resumable bit for bit.
        self.generator = torch.Generator().manual_seed(int(seed))
        self.frames_seen = 0
        self.steps = 0
        self.warmed_up = False
        self.camera_points_total = 0
        self.tactile_points_total = 0

    # ------------------------------------------------------------------ ingestion
    def frame_points(self, frame: Frame, world_T_object: np.ndarray) -> dict[str, np.ndarray]:
        """Object-frame surface points per source: `camera` and each finger in contact."""
        return self._frame_points(frame, world_T_object, every_pixel=False)[0]

    def _frame_points(
        self, frame: Frame, world_T_object: np.ndarray, every_pixel: bool
    ) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
        """frame_points and, with `every_pixel`, the points of all valid camera pixels.

        The space prior carves along every pixel's ray, mask or not: for it the camera is
        back-projected once, without its mask, and the surface points are the pixels inside
        the mask (the same points, in the same order, as camera_points(..., use_mask=True)).
        """
        out: dict[str, np.ndarray] = {}
        every = None
        reading = frame.camera
        if reading is not None and every_pixel:
            every = camera_points(reading, world_T_object, use_mask=False)
            out["camera"] = every
            if self.use_camera_mask and reading.mask is not None:
                if reading.mask.shape != reading.depth.shape:
                    raise ValueError(
                        f"mask shape {reading.mask.shape} does not match depth shape "
                        f"{reading.depth.shape}"
                    )
                # backproject keeps the finite, positive depths in row-major pixel order.
                valid = np.isfinite(reading.depth) & (reading.depth > 0)
                out["camera"] = every[reading.mask.astype(bool)[valid]]
        elif reading is not None:
            out["camera"] = camera_points(reading, world_T_object, self.use_camera_mask)
        for finger, reading in frame.tactile.items():
            pts = tactile_points(reading, self.tactile_depth(reading), world_T_object)
            if len(pts):
                out[finger] = pts
        return out, every

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(array, dtype=np.float32), device=self.device)

    def add_frame(
        self,
        frame: Frame,
        touch_labels: Mapping[str, TouchLabel] | None = None,
        world_T_object: np.ndarray | None = None,
    ) -> dict[str, float]:
        """Ingest one frame, then run steps_per_frame (first time: warmup_steps) steps."""
        pose = frame.world_T_object if world_T_object is None else world_T_object
        if not np.isfinite(pose).all():
            raise NumericalError(
                f"the object pose for frame {frame.index} is not finite (NaN/inf); "
                "the pose source diverged: try mapping.pose=gt"
            )
        touch_labels = touch_labels or {}
        points, every_pixel = self._frame_points(frame, pose, self.space_prior is not None)
        for source, pts in points.items():
            if source == "camera":
                keep = subsample(
                    len(pts), self.camera_points_per_frame, self.generator, replace_if_short=False
                )
                origin, _ = sensor_origin_and_axis(frame.camera.world_T_camera, pose)
                self.keyframes.add(
                    self._tensor(pts[keep.numpy()]), self._tensor(origin), frame.index
                )
                if self.space_prior is not None:
                    # Every pixel's ray, hand and background included, crosses free space.
                    self.space_prior.carve(origin, every_pixel, self.truncation)
                    self.space_prior.add_surface(pts[keep.numpy()])
                self.camera_points_total += len(keep)
            else:
                keep = subsample(
                    len(pts), self.tactile_points_per_touch, self.generator, replace_if_short=True
                )
                _, axis = sensor_origin_and_axis(frame.tactile[source].world_T_sensor, pose)
                if self.space_prior is not None:
                    self.space_prior.add_surface(pts[keep.numpy()])
                label = touch_labels.get(source)
                usable = label is not None and label.usable
                self.touches.add(
                    self._tensor(pts[keep.numpy()]),
                    self._tensor(axis),
                    label.label if usable else -1,
                    label.confidence if usable else 0.0,
                    finger=source,
                    frame_index=frame.index,
                )
                self.tactile_points_total += len(keep)
        self.frames_seen += 1
        if self.space_prior is not None:
            self.space_prior.update_hull()
        if not self.has_data:
            return dict.fromkeys(LOSS_KEYS, 0.0)
        steps = self.steps_per_frame
        if not self.warmed_up:
            steps, self.warmed_up = max(steps, self.warmup_steps), True
        return self.optimize(steps)

    @property
    def has_data(self) -> bool:
        return len(self.keyframes) > 0 or self.touches.num_touches > 0

    @property
    def trained_on(self) -> dict:
        """What the field actually learned from (docs/design.md: metrics.json `trained_on`)."""
        return {
            "frames": self.frames_seen,
            "camera_points": self.camera_points_total,
            "tactile_points": self.tactile_points_total,
            "touches": self.touches.num_touches,
            "labelled_touches": self.touches.num_labelled,
            "outvoted_touches": self.touches.num_outvoted,
            "optimizer_steps": self.steps,
        }

    # ------------------------------------------------------------------ optimisation
    def optimize(self, steps: int) -> dict[str, float]:
        """Run `steps` optimiser steps on the stored data; mean of each loss over them."""
        if not self.has_data:
            raise NoDataError(
                "the mapper has no camera or tactile points yet; feed frames with data first"
            )
        totals = dict.fromkeys(LOSS_KEYS, 0.0)
        for _ in tqdm(range(steps), desc="mapping", unit="step", leave=False, disable=steps < 100):
            for key, value in self.step().items():
                totals[key] += value
        return {k: v / max(steps, 1) for k, v in totals.items()}

    def _camera_rays(self) -> tuple[RaySamples, torch.Tensor, list[int]] | None:
        if len(self.keyframes) == 0 or self.camera_rays == 0:
            return None
        window = self.keyframes.window(self.generator)
        counts = torch.tensor([self.keyframes.points[i].shape[0] for i in window])
        which = torch.randint(len(window), (self.camera_rays,), generator=self.generator)
        within = (torch.rand(self.camera_rays, generator=self.generator) * counts[which]).long()
        offsets = torch.cumsum(counts, 0) - counts
        idx = (offsets[which] + within).to(self.device)
        points = torch.cat([self.keyframes.points[i] for i in window])[idx]
        origins = torch.stack([self.keyframes.origins[i] for i in window])[which.to(self.device)]
        ray = points - origins
        length = ray.norm(dim=1)
        samples = sample_along_rays(
            points, ray / length.clamp_min(1e-9).unsqueeze(1), length, self.band_samples,
            self.free_samples, self.truncation, self.camera_free_range, self.generator,
        )  # fmt: skip
        return samples, which.to(self.device), window

    def _tactile_rays(self) -> RaySamples | None:
        touch = self.touches.tensors()
        idx = random_indices(len(touch["points"]), self.tactile_rays, self.generator, self.device)
        if len(idx) == 0:
            return None
        length = torch.full((len(idx),), self.tactile_free_range, device=self.device)
        return sample_along_rays(
            touch["points"][idx], touch["axes"][idx], length, self.band_samples, self.free_samples,
            self.truncation, self.tactile_free_range, self.generator,
        )  # fmt: skip

    def step(self) -> dict[str, float]:
        """One optimiser step on a fresh batch; returns its losses."""
        camera = self._camera_rays()
        tactile = self._tactile_rays()
        parts = [(camera[0], self.camera_weight)] if camera else []
        parts += [(tactile, self.tactile_weight)] if tactile else []
        touch = self.touches.tensors()
        pick = random_indices(
            len(touch["labelled_points"]), self.material_points, self.generator, self.device
        )
        x_mat = touch["labelled_points"][pick]
        # Space-prior points (cube samples with a target sign), none until the hull exists.
        x_space, sign_space = x_mat[:0], x_mat[:0, 0]
        if self.space_prior is not None and self.space_prior.ready:
            x_space, sign_space = self.space_prior.sample(
                self.space_prior_points, self.truncation, self.generator, self.device
            )
        x = torch.cat([p.x for p, _ in parts] + [x_space, x_mat])
        n_geo = len(x) - len(x_space) - len(x_mat)
        # One pass for geometry and material points: the hash grid dominates the cost.
        out = self.field(x)
        zero = torch.zeros((), device=self.device)
        losses = dict.fromkeys(("sdf", "freespace", "space", "eikonal", "material"), zero)
        if parts:
            sdf = out["sdf"][:n_geo]
            s = torch.cat([p.s for p, _ in parts])
            free = torch.cat([p.free for p, _ in parts])
            weight = torch.cat(
                [torch.full((len(p),), float(w), device=self.device) for p, w in parts]
            )
            bound = batch_bound(x[:n_geo], s, torch.cat([p.surface for p, _ in parts]))
            per_sample = (
                torch.where(free, freespace_loss(sdf, bound), truncated_sdf_loss(sdf, s, bound))
                * weight
            )
            losses["sdf"] = per_sample[~free].sum() / max(int((~free).sum()), 1)
            losses["freespace"] = per_sample[free].sum() / max(int(free.sum()), 1)
            if self.eikonal_weight > 0 and self.eikonal_points > 0:
                idx = random_indices(n_geo, self.eikonal_points, self.generator, self.device)
                xe = x[idx].detach().requires_grad_(True)
                (grad,) = torch.autograd.grad(self.field.sdf(xe).sum(), xe, create_graph=True)
                losses["eikonal"] = eikonal_loss(grad).mean()
            if camera:
                self._update_keyframe_losses(camera, per_sample[: len(camera[0])].detach())
        if len(x_space):
            sdf_space = out["sdf"][n_geo : n_geo + len(x_space)]
            losses["space"] = space_prior_loss(sdf_space, sign_space).mean()
        if len(x_mat):
            logits = out["material_logits"][n_geo + len(x_space) :]
            labels, weights = touch["labelled_labels"][pick], touch["labelled_weights"][pick]
            losses["material"] = material_loss(logits, labels, weights).mean()
        total = (
            self.sdf_weight * losses["sdf"]
            + self.freespace_weight * losses["freespace"]
            + self.space_prior_weight * losses["space"]
            + self.eikonal_weight * losses["eikonal"]
            + self.material_weight * losses["material"]
        )
        if not torch.isfinite(total):
            bad = [k for k, v in losses.items() if not torch.isfinite(v)]
            raise NumericalError(
                f"mapper loss is not finite at step {self.steps} ({', '.join(bad) or 'total'}); "
                "lower mapping.optimizer.lr or check the input depth and poses"
            )
        self.optimizer.zero_grad(set_to_none=True)
        total.backward()
        self.optimizer.step()
        self.steps += 1
        n_points = len(x) + (self.eikonal_points if self.eikonal_weight > 0 and parts else 0)
        result = {k: float(v.detach()) for k, v in losses.items()}
        result.update(total=float(total.detach()), points=float(n_points))
        return result

    def _update_keyframe_losses(
        self, camera: tuple[RaySamples, torch.Tensor, list[int]], loss: torch.Tensor
    ) -> None:
        samples, which, window = camera
        per_kf = torch.zeros(len(window), device=self.device).index_add_(
            0, which[samples.ray], loss
        )
        hits = torch.zeros(len(window), device=self.device).index_add_(
            0, which[samples.ray], torch.ones_like(loss)
        )
        mean = (per_kf / hits.clamp_min(1)).tolist()
        used = hits.tolist()
        self.keyframes.update_losses(
            [w for w, h in zip(window, used) if h > 0], [m for m, h in zip(mean, used) if h > 0]
        )

    # ------------------------------------------------------------------ state
    def state_dict(self) -> dict:
        """Everything needed to continue bit for bit (loads with torch.load(weights_only=True))."""
        np_state = np.random.get_state()
        return {
            "field": self.field.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "keyframes": self.keyframes.state_dict(),
            "touches": self.touches.state_dict(),
            "space_prior": self.space_prior.state_dict() if self.space_prior is not None else {},
            "counters": {
                "frames_seen": self.frames_seen,
                "steps": self.steps,
                "warmed_up": self.warmed_up,
                "camera_points_total": self.camera_points_total,
                "tactile_points_total": self.tactile_points_total,
            },
            "rng": {
                "mapper": self.generator.get_state(),
                "torch": torch.get_rng_state(),
                "python": random.getstate(),
                "numpy": {
                    "keys": torch.from_numpy(np_state[1].astype(np.int64)),
                    "pos": int(np_state[2]),
                    "has_gauss": int(np_state[3]),
                    "cached_gaussian": float(np_state[4]),
                },
            },
        }

    def load_state_dict(self, state: dict) -> None:
        self.field.load_state_dict(state["field"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.keyframes.load_state_dict(state["keyframes"], self.device)
        self.touches.load_state_dict(state["touches"])
        if self.space_prior is not None and state.get("space_prior"):
            self.space_prior.load_state_dict(state["space_prior"])
        counters = state["counters"]
        self.frames_seen = int(counters["frames_seen"])
        self.steps = int(counters["steps"])
        self.warmed_up = bool(counters["warmed_up"])
        self.camera_points_total = int(counters["camera_points_total"])
        self.tactile_points_total = int(counters["tactile_points_total"])
        rng = state["rng"]
        self.generator.set_state(rng["mapper"])
        torch.set_rng_state(rng["torch"])
        random.setstate(rng["python"])
        npr = rng["numpy"]
        np.random.set_state(
            (
                "MT19937",
                npr["keys"].numpy().astype(np.uint32),
                npr["pos"],
                npr["has_gauss"],
                npr["cached_gaussian"],
            )
        )
