"""OnlineMapper on analytic sphere scenes: points, counts, SDF fit, material split, label gating."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.errors import ConfigError, NoDataError, NumericalError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.core.geometry import rotation_matrix
from neuralfeels_sem.mapping.mapper import MapperConfig, OnlineMapper
from neuralfeels_sem.mapping.pose_source import resolve_pose_source
from neuralfeels_sem.perception.pointcloud import camera_points
from neuralfeels_sem.perception.touch import TouchLabel
from tests.mapping.synthetic import (
    RADIUS,
    fibonacci_directions,
    small_field,
    small_mapper,
    sphere_frames,
    sphere_surface,
    true_label,
)


def make_mapper(
    concat: bool = True, material_grid_levels: int | None = None, **kwargs
) -> OnlineMapper:
    """The command line's mapper (MapperConfig defaults), smaller batches, `kwargs` changed."""
    torch.manual_seed(0)
    args = dict(
        steps_per_frame=10, warmup_steps=40, camera_rays=128, tactile_rays=64,
        band_samples=3, free_samples=2, material_points=256, seed=0,
    )  # fmt: skip
    args.update(kwargs)
    field = small_field(concat, log2_table_size=14, material_grid_levels=material_grid_levels)
    return small_mapper(field, **args)


def test_frame_points_use_the_given_pose() -> None:
    frame, _ = sphere_frames(1, touches_per_frame=2)[0]
    mapper = make_mapper(steps_per_frame=1, warmup_steps=1)
    points = mapper.frame_points(frame, frame.world_T_object)
    assert set(points) == {"camera", "index", "middle"}
    for source, pts in points.items():
        assert np.abs(np.linalg.norm(pts, axis=1) - RADIUS).max() < 0.5e-3, source
    # Another pose (e.g. from a tracker) moves every point accordingly.
    moved = frame.world_T_object.copy()
    moved[:3, :3] = moved[:3, :3] @ rotation_matrix(np.array([0.0, 0.0, 1.0]), 0.3)
    moved[:3, 3] += [0.01, 0.0, 0.0]
    shifted = mapper.frame_points(frame, moved)["camera"]
    assert np.abs(np.linalg.norm(shifted, axis=1) - RADIUS).mean() > 2e-3
    mapper.add_frame(frame, world_T_object=moved)
    stored = mapper.memory.keyframes.points[0].numpy()
    assert np.abs(np.linalg.norm(stored, axis=1) - RADIUS).mean() > 2e-3


@pytest.mark.parametrize("camera_mask", ["gt", "none"])
def test_one_unmasked_back_projection_gives_the_masked_surface_points(
    camera_mask: str,
) -> None:
    """add_frame back-projects the camera once for both the surface and the carving rays."""
    frame, _ = sphere_frames(1, touches_per_frame=0)[0]
    camera = frame.camera
    # Invalid depths inside and outside the mask, and a mask that cuts through the sphere.
    depth = camera.depth.copy()
    v, u = np.nonzero(depth > 0)
    depth[v[::7], u[::7]] = np.nan
    depth[v[3::11], u[3::11]] = 0.0
    mask = np.zeros(depth.shape, dtype=bool)
    mask[:, : depth.shape[1] // 2] = True
    frame = dataclasses.replace(frame, camera=dataclasses.replace(camera, depth=depth, mask=mask))
    mapper = make_mapper(space_prior_points=64, camera_mask=camera_mask)
    pose = frame.world_T_object
    points, every = mapper.points.extract(frame, pose, every_pixel=True)
    assert np.array_equal(every, camera_points(frame.camera, pose, use_mask=False))
    assert np.array_equal(points["camera"], camera_points(frame.camera, pose, camera_mask == "gt"))
    assert np.array_equal(points["camera"], mapper.frame_points(frame, pose)["camera"])
    if camera_mask == "gt":
        assert 0 < len(points["camera"]) < len(every)
    else:
        assert points["camera"] is every


def test_counts_losses_and_warmup() -> None:
    frames = sphere_frames(3, touches_per_frame=2)
    # Exact counts: without the space prior (its share varies per step) and the label vote
    # (it would leave out these few far-apart touches); both are counted in the next test.
    mapper = make_mapper(
        camera_points_per_frame=500, tactile_points_per_touch=64, steps_per_frame=2,
        warmup_steps=5, space_prior_points=0, label_vote_radius=0.0,
    )  # fmt: skip
    labels = dict(frames[0][1])
    labels["middle"] = TouchLabel(
        "middle", contact=True, label=1, confidence=0.3, low_confidence=True
    )
    losses = mapper.add_frame(frames[0][0], labels)
    assert set(losses) == {"total", "sdf", "freespace", "space", "eikonal", "material", "points"}
    assert losses["points"] == 128 * 6 + 64 * 6 + 256
    assert losses["material"] > 0 and losses["eikonal"] == 0
    for frame, labels in frames[1:]:
        mapper.add_frame(frame, labels)
    assert mapper.trained_on == {
        "frames": 3, "camera_points": 1500, "tactile_points": 6 * 64, "touches": 6,
        "labelled_touches": 5, "fused_touches": 0, "outvoted_touches": 0,
        "optimizer_steps": 5 + 2 + 2,
    }  # fmt: skip


def test_the_command_lines_space_prior_and_label_vote_show_in_the_counts() -> None:
    frames = sphere_frames(3, touches_per_frame=2)
    mapper = make_mapper(steps_per_frame=2, warmup_steps=5)
    geometry = 128 * 6 + 64 * 6
    for frame, labels in frames:
        losses = mapper.add_frame(frame, labels)
        # The prior's points (up to 512 per step, fewer where its sign is ambiguous).
        assert geometry + 256 < losses["points"] <= geometry + 512 and losses["space"] > 0
    trained = mapper.trained_on
    # Six lone presses, none backed by another within 4 cm: the vote leaves all out.
    assert trained["labelled_touches"] == trained["outvoted_touches"] == 6
    assert losses["material"] == 0


def test_empty_frames_train_nothing_and_optimize_needs_data() -> None:
    mapper = make_mapper()
    frame = Frame(index=0, time_s=0.0, world_T_object=np.eye(4))
    assert mapper.add_frame(frame)["points"] == 0
    assert mapper.trained_on["optimizer_steps"] == 0
    with pytest.raises(NoDataError):
        mapper.optimize(3)


def test_pose_source() -> None:
    for pose in ("gt", "track", "track_known_shape"):  # tracking: mapping/pose_source.py
        assert resolve_pose_source(pose) == pose
    with pytest.raises(ConfigError, match="unknown"):
        resolve_pose_source("vicon")


@pytest.mark.parametrize("label_kind", ["none", "low_confidence", "no_contact"])
def test_unlabelled_touches_do_not_train_the_material_branch(label_kind: str) -> None:
    frames = sphere_frames(1, touches_per_frame=4)
    # Vote off: it would leave out these four lone touches even with usable labels.
    mapper = make_mapper(steps_per_frame=2, warmup_steps=2, label_vote_radius=0.0)
    before = {k: v.clone() for k, v in mapper.field.material_head.state_dict().items()}
    sdf_before = {k: v.clone() for k, v in mapper.field.sdf_head.state_dict().items()}
    for frame, labels in frames:
        if label_kind == "none":
            labels = None
        else:
            labels = {
                f: TouchLabel(f, contact=label_kind != "no_contact", label=lab.label, confidence=0.4, low_confidence=label_kind == "low_confidence")
                for f, lab in labels.items()
            }  # fmt: skip
        losses = mapper.add_frame(frame, labels)
        assert losses["material"] == 0
    assert mapper.trained_on["labelled_touches"] == 0 and mapper.trained_on["touches"] == 4
    for key, value in mapper.field.material_head.state_dict().items():
        assert torch.equal(value, before[key]), key
    assert any(
        not torch.equal(v, sdf_before[k]) for k, v in mapper.field.sdf_head.state_dict().items()
    )
    # The same frames with usable labels do move the material branch.
    for frame, labels in frames:
        mapper.add_frame(frame, labels)
    assert any(
        not torch.equal(v, before[k]) for k, v in mapper.field.material_head.state_dict().items()
    )


def test_a_few_steps_pull_the_sdf_toward_the_truth() -> None:
    """Fast check that optimisation works at all (the full fit below is marked slow)."""
    mapper = make_mapper(steps_per_frame=1, warmup_steps=1)
    frame, labels = sphere_frames(1, touches_per_frame=4)[0]
    mapper.add_frame(frame, labels)
    surface = torch.tensor(
        mapper.frame_points(frame, frame.world_T_object)["camera"], dtype=torch.float32
    )
    normals = surface / surface.norm(dim=1, keepdim=True)

    def band_error() -> float:
        with torch.no_grad():
            return (
                sum(
                    (mapper.field.sdf(surface + d * normals) - d).abs().mean().item()
                    for d in (-0.003, 0.003)
                )
                / 2
            )

    before = band_error()
    mapper.optimize(40)
    after = band_error()
    assert before > 2e-3  # an untrained field is near zero everywhere
    assert after < 0.5 * before, (before, after)


@pytest.mark.slow
def test_field_fits_sphere_sdf_below_2mm() -> None:
    mapper = make_mapper()
    for frame, labels in sphere_frames(10, touches_per_frame=4):
        mapper.add_frame(frame, labels)
    directions = torch.tensor(fibonacci_directions(2000), dtype=torch.float32)
    with torch.no_grad():
        surface = mapper.field.sdf(directions * RADIUS).abs().mean().item()
        band = [
            (mapper.field.sdf(directions * (RADIUS + d)) - d).abs().mean().item()
            for d in (-0.003, 0.003)
        ]
    assert surface < 2e-3, surface
    assert max(band) < 2e-3, band


# Measured agreement: 0.985 without the material grid (the paper's branch), 0.964 with the
# default grid, which extrapolates less far from the sparse touches into the untouched band.
@pytest.mark.slow
@pytest.mark.parametrize(
    ("concat", "grid_levels", "sampling", "least"),
    [
        (True, 0, "uniform", 0.98),
        (False, 0, "uniform", 0.98),
        (False, None, "uniform", 0.95),
        (False, None, "balanced", 0.95),
        (False, None, "tempered", 0.95),
    ],
)
def test_material_split_from_sparse_touches(
    concat: bool, grid_levels: int | None, sampling: str, least: float
) -> None:
    mapper = make_mapper(
        concat, grid_levels, steps_per_frame=15, warmup_steps=30, material_sampling=sampling
    )
    for frame, labels in sphere_frames(16, touches_per_frame=4, camera=False):
        mapper.add_frame(frame, labels)
    surface = sphere_surface(4000)
    predicted = mapper.field.predict_material(torch.tensor(surface, dtype=torch.float32)).numpy()
    agreement = (predicted == true_label(surface)).mean()
    assert agreement >= least, agreement


@pytest.mark.parametrize("share", [0.0, 0.25, 1.0])
def test_recent_share_draws_that_share_from_the_newest_frames_touches(share: float) -> None:
    mapper = make_mapper(
        steps_per_frame=1, warmup_steps=1, label_vote_radius=0.0,
        material_recent_share=share, material_recent_frames=2,
    )  # fmt: skip
    for frame, labels in sphere_frames(6, touches_per_frame=2, camera=False):
        mapper.add_frame(frame, labels)
    touch = mapper.memory.touches.tensors()
    newest = mapper.memory.touches.newest_frame
    assert newest == int(touch["labelled_frames"].max())
    from_recent = torch.zeros(0, dtype=torch.long)
    for _ in range(20):  # draws are random; the split is exact on every step
        pick = mapper.sampler._material_pick(touch)
        assert len(pick) == 256
        from_recent = torch.cat([from_recent, touch["labelled_frames"][pick] > newest - 2])
    assert int(from_recent.sum()) >= round(share * 256) * 20
    if share == 1.0:
        assert bool(from_recent.all())


def test_eikonal_term_trains_through_the_sparse_hash_grid() -> None:
    # Exact point count: no space prior, no vote (as in test_counts_losses_and_warmup).
    mapper = make_mapper(
        steps_per_frame=2, warmup_steps=2, eikonal_weight=0.1, eikonal_points=64,
        space_prior_points=0, label_vote_radius=0.0,
    )  # fmt: skip
    frame, labels = sphere_frames(1, touches_per_frame=1)[0]
    losses = mapper.add_frame(frame, labels)
    assert losses["eikonal"] > 0
    assert losses["points"] == 128 * 6 + 64 * 6 + 256 + 64
    assert mapper.trained_on["optimizer_steps"] == 2


@pytest.mark.parametrize(
    "bad",
    [
        {"num_classes": 1},
        {"truncation": 0.0},
        {"steps_per_frame": -1},
        {"steps_policy": "adaptive"},
        {"material_sampling": "stratified"},
        {"material_temper_power": 1.5},
        {"material_recent_share": -0.1},
        {"material_recent_frames": 0},
    ],
)
def test_bad_settings_are_refused_by_the_config(bad: dict) -> None:
    with pytest.raises(ValueError, match=next(iter(bad))):
        MapperConfig(**bad)


def test_a_field_with_another_class_count_is_refused() -> None:
    with pytest.raises(ConfigError, match="classes"):
        small_mapper(small_field(log2_table_size=10), num_classes=3)


def test_non_finite_pose_or_loss_is_a_one_line_numerical_error() -> None:
    frame, labels = sphere_frames(1, touches_per_frame=2)[0]
    mapper = make_mapper(steps_per_frame=1, warmup_steps=1)
    bad_pose = frame.world_T_object.copy()
    bad_pose[0, 3] = np.nan
    with pytest.raises(NumericalError, match="pose for frame .* not finite"):
        mapper.add_frame(frame, labels, world_T_object=bad_pose)
    mapper.add_frame(frame, labels)
    with torch.no_grad():  # a diverged field: NaN everywhere
        for p in mapper.field.sdf_head.parameters():
            p.fill_(float("nan"))
    with pytest.raises(NumericalError, match="loss is not finite"):
        mapper.optimize(1)
