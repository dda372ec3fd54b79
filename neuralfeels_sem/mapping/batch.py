"""One training batch drawn from the mapper's memory, for one pass through the field.

Per step: `camera_rays` rays from the keyframe window and `tactile_rays` from all touches,
each sampled at the surface, in the truncation band and in free space (sampling.py);
`space_prior_points` points of the space-carving prior once its hull exists; and
`material_points` labelled touch points (uniformly, or `balanced`: an equal share per
material). The field sees them all in one pass, in this
order: geometry samples (camera then tactile rays), space-prior points, material points.
The draws come from the mapper's generator in a fixed order, so a run is repeatable.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from neuralfeels_sem.mapping.memory import MapMemory
from neuralfeels_sem.mapping.sampling import (
    RaySamples,
    balanced_indices,
    label_groups,
    random_indices,
    sample_along_rays,
)

if TYPE_CHECKING:
    from neuralfeels_sem.mapping.mapper import MapperConfig

MATERIAL_SAMPLINGS = ("uniform", "balanced", "tempered")  # mapping.mapper.material_sampling


@dataclass
class CameraRays:
    """Camera ray samples and where they came from: `which` (R,) indexes `window`."""

    samples: RaySamples
    which: torch.Tensor
    window: list[int]  # keyframe indices


@dataclass
class Batch:
    x: torch.Tensor  # (N, 3): geometry samples, then space-prior points, then material points
    rays: list[tuple[RaySamples, float]]  # geometry samples per source, with its loss weight
    camera: CameraRays | None
    space_sign: torch.Tensor  # (S,) target sign of the space-prior points (+1 out, -1 solid)
    space_floor: torch.Tensor  # (S,) metres an outside point's SDF must reach (0: solid)
    material_labels: torch.Tensor  # (M,)
    material_weights: torch.Tensor  # (M,) classifier confidence

    @property
    def num_geometry(self) -> int:
        return len(self.x) - len(self.space_sign) - len(self.material_labels)


class BatchSampler:
    """Draws Batches from a MapMemory with the mapper's generator."""

    def __init__(
        self,
        config: MapperConfig,
        memory: MapMemory,
        generator: torch.Generator,
        device: torch.device,
    ) -> None:
        self.memory = memory
        self.generator = generator
        self.device = device
        self.camera_rays = config.camera_rays
        self.tactile_rays = config.tactile_rays
        self.band_samples = config.band_samples
        self.free_samples = config.free_samples
        self.material_points = config.material_points
        self.material_sampling = config.material_sampling
        # A material's share of the draws grows with its point count to this power.
        self.material_power = {"balanced": 0.0, "tempered": config.material_temper_power}.get(
            config.material_sampling, 1.0
        )
        self.recent_share = float(config.material_recent_share)
        self.recent_frames = config.material_recent_frames
        self._grouped: tuple | None = None  # (labels, label_groups(labels)) of the last step
        self.space_prior_points = config.space_prior_points
        self.space_prior_margin = float(config.space_prior_margin)
        self.truncation = float(config.truncation)
        self.camera_free_range = float(config.camera_free_range)
        self.tactile_free_range = float(config.tactile_free_range)
        self.camera_weight = config.camera_weight
        self.tactile_weight = config.tactile_weight

    def sample(self) -> Batch:
        camera = self._camera_rays()
        tactile = self._tactile_rays()
        rays = [(camera.samples, self.camera_weight)] if camera else []
        rays += [(tactile, self.tactile_weight)] if tactile else []
        touch = self.memory.touches.tensors()
        pick = self._material_pick(touch)
        x_mat = touch["labelled_points"][pick]
        # Space-prior points (cube samples with a target sign), none until the hull exists.
        x_space, sign_space, floor_space = x_mat[:0], x_mat[:0, 0], x_mat[:0, 0]
        prior = self.memory.space_prior
        if prior is not None and prior.ready:
            x_space, sign_space, floor_space = prior.sample(
                self.space_prior_points,
                self.truncation,
                self.generator,
                self.device,
                self.space_prior_margin,
            )
        return Batch(
            x=torch.cat([r.x for r, _ in rays] + [x_space, x_mat]),
            rays=rays,
            camera=camera,
            space_sign=sign_space,
            space_floor=floor_space,
            material_labels=touch["labelled_labels"][pick],
            material_weights=touch["labelled_weights"][pick],
        )

    def _material_pick(self, touch: dict[str, torch.Tensor]) -> torch.Tensor:
        """This step's labelled touch points for the material loss: `recent_share` of them
        from the newest `recent_frames` frames' touches, the rest by `material_sampling`."""
        g, device, recent = self.generator, self.device, self._recent_points(touch)
        n_recent = round(self.recent_share * self.material_points) if len(recent) else 0
        n_rest = self.material_points - n_recent
        if self.material_sampling != "uniform":
            groups = self._groups(touch["labelled_labels"])
            rest = balanced_indices(groups, n_rest, g, device, self.material_power)
        else:
            rest = random_indices(len(touch["labelled_points"]), n_rest, g, device)
        return torch.cat([recent[random_indices(len(recent), n_recent, g, device)], rest])

    def _recent_points(self, touch: dict[str, torch.Tensor]) -> torch.Tensor:
        """Indices of the labelled points whose touches came in the newest frames."""
        if self.recent_share == 0.0:
            return torch.zeros(0, dtype=torch.long, device=self.device)
        oldest = self.memory.touches.newest_frame - self.recent_frames
        return torch.nonzero(touch["labelled_frames"] > oldest).flatten().to(self.device)

    def _groups(self, labels: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """label_groups of the touches' labels, kept while the touch memory's tensors are."""
        if self._grouped is None or self._grouped[0] is not labels:
            self._grouped = (labels, label_groups(labels))
        return self._grouped[1]

    def _camera_rays(self) -> CameraRays | None:
        keyframes = self.memory.keyframes
        if len(keyframes) == 0 or self.camera_rays == 0:
            return None
        g = self.generator
        window = keyframes.window(g)
        counts = torch.tensor([keyframes.points[i].shape[0] for i in window])
        which = torch.randint(len(window), (self.camera_rays,), generator=g)
        within = (torch.rand(self.camera_rays, generator=g) * counts[which]).long()
        offsets = torch.cumsum(counts, 0) - counts
        idx = (offsets[which] + within).to(self.device)
        points = torch.cat([keyframes.points[i] for i in window])[idx]
        origins = torch.stack([keyframes.origins[i] for i in window])[which.to(self.device)]
        ray = points - origins
        length = ray.norm(dim=1)
        samples = sample_along_rays(
            points, ray / length.clamp_min(1e-9).unsqueeze(1), length, self.band_samples,
            self.free_samples, self.truncation, self.camera_free_range, g,
        )  # fmt: skip
        return CameraRays(samples, which.to(self.device), window)

    def _tactile_rays(self) -> RaySamples | None:
        touch = self.memory.touches.tensors()
        idx = random_indices(len(touch["points"]), self.tactile_rays, self.generator, self.device)
        if len(idx) == 0:
            return None
        length = torch.full((len(idx),), self.tactile_free_range, device=self.device)
        return sample_along_rays(
            touch["points"][idx], touch["axes"][idx], length, self.band_samples, self.free_samples,
            self.truncation, self.tactile_free_range, self.generator,
        )  # fmt: skip


def per_keyframe_losses(camera: CameraRays, loss: torch.Tensor) -> tuple[list[int], list[float]]:
    """Mean per-sample loss (R * K,) of each keyframe in the window that got a ray."""
    samples, which, window = camera.samples, camera.which, camera.window
    device = loss.device
    per_kf = torch.zeros(len(window), device=device).index_add_(0, which[samples.ray], loss)
    hits = torch.zeros(len(window), device=device).index_add_(
        0, which[samples.ray], torch.ones_like(loss)
    )
    mean = (per_kf / hits.clamp_min(1)).tolist()
    used = hits.tolist()
    return [w for w, h in zip(window, used) if h > 0], [m for m, h in zip(mean, used) if h > 0]
