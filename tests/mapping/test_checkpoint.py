"""Checkpoints: exact resume after a simulated kill, atomic writes, clear errors."""

from __future__ import annotations

import random

import numpy as np
import pytest
import torch

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.mapping import checkpoint as checkpoint_module
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, save_checkpoint
from neuralfeels_sem.mapping.mapper import OnlineMapper
from tests.mapping.synthetic import small_field, small_mapper, sphere_frames

FRAMES = sphere_frames(6, touches_per_frame=2)


def make_mapper(
    init_seed: int = 0, log2_table_size: int = 12, space_prior_points: int = 0
) -> OnlineMapper:
    """The command line's mapper at toy size (the label vote on, the space prior as asked)."""
    torch.manual_seed(init_seed)
    return small_mapper(
        small_field(log2_table_size=log2_table_size),
        steps_per_frame=2,
        warmup_steps=4,
        camera_rays=32,
        tactile_rays=16,
        material_points=16,
        window_recent=2,
        window_by_loss=1,
        space_prior_points=space_prior_points,
        space_prior_resolution=16,
        seed=3,
    )


def feed(mapper: OnlineMapper, frames) -> None:
    for frame, labels in frames:
        mapper.add_frame(frame, labels)


@pytest.mark.parametrize("space_prior_points", [0, 64])
def test_resume_after_kill_matches_uninterrupted_run(tmp_path, space_prior_points: int) -> None:
    reference = make_mapper(space_prior_points=space_prior_points)
    feed(reference, FRAMES)

    first = make_mapper(space_prior_points=space_prior_points)
    feed(first, FRAMES[:3])
    path = tmp_path / "checkpoint.pt"
    save_checkpoint(path, first, frame_index=2, extra={"matching_curve": [[2, 0.2, 51.0]]})
    del first
    # A new process: different global RNG states and a differently initialised field.
    torch.manual_seed(99)
    random.seed(99)
    np.random.seed(99)
    resumed = make_mapper(init_seed=7, space_prior_points=space_prior_points)
    info = load_checkpoint(path, resumed)
    assert info == {"frame_index": 2, "extra": {"matching_curve": [[2, 0.2, 51.0]]}}
    feed(resumed, FRAMES[info["frame_index"] + 1 :])

    for (name, a), (_, b) in zip(
        reference.field.state_dict().items(), resumed.field.state_dict().items()
    ):
        assert torch.equal(a, b), name
    assert reference.trained_on == resumed.trained_on
    ref_opt, res_opt = (
        reference.optimizer.state_dict()["state"],
        resumed.optimizer.state_dict()["state"],
    )
    assert ref_opt.keys() == res_opt.keys()
    for key, state in ref_opt.items():
        for name, value in state.items():
            same = (
                torch.equal(value, res_opt[key][name])
                if torch.is_tensor(value)
                else value == res_opt[key][name]
            )
            assert same, (key, name)
    assert reference.memory.keyframes.losses == resumed.memory.keyframes.losses
    if space_prior_points:
        ref_prior, res_prior = reference.memory.space_prior, resumed.memory.space_prior
        assert np.array_equal(ref_prior.carved, res_prior.carved)
        assert np.array_equal(ref_prior.hull_points, res_prior.hull_points)


def test_kill_during_write_keeps_the_last_good_checkpoint(tmp_path, monkeypatch) -> None:
    mapper = make_mapper()
    feed(mapper, FRAMES[:1])
    path = tmp_path / "checkpoint.pt"
    save_checkpoint(path, mapper, frame_index=0)
    good = path.read_bytes()
    feed(mapper, FRAMES[1:2])

    def dies_half_way(obj, f, *args, **kwargs):
        f.write(b"PK\x03\x04 half a zip")
        raise KeyboardInterrupt  # the kill arrives mid-write

    monkeypatch.setattr(checkpoint_module.torch, "save", dies_half_way)
    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(path, mapper, frame_index=1)
    monkeypatch.undo()
    assert path.read_bytes() == good
    assert load_checkpoint(path, make_mapper())["frame_index"] == 0


def test_different_model_is_a_one_line_config_error(tmp_path) -> None:
    path = tmp_path / "checkpoint.pt"
    mapper = make_mapper()
    feed(mapper, FRAMES[:1])
    save_checkpoint(path, mapper, frame_index=0, model_config={"center": [0.0, 0.0, 0.0]})
    with pytest.raises(ConfigError) as info:
        load_checkpoint(path, make_mapper(log2_table_size=13))
    assert "shapes" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="model.center"):
        load_checkpoint(path, make_mapper(), model_config={"center": [0.0, 0.0, 0.01]})


def test_missing_or_corrupt_checkpoint_is_a_data_error(tmp_path) -> None:
    with pytest.raises(DataError, match="does not exist"):
        load_checkpoint(tmp_path / "nope.pt", make_mapper())
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(DataError, match="unreadable"):
        load_checkpoint(bad, make_mapper())


def test_a_checkpoint_from_before_bound_left_the_model_config_still_loads(tmp_path) -> None:
    """Older runs saved `_target_`, `_convert_` and the declared `bound` in the model config;
    none is a model setting (the bound is computed from the object), so resuming ignores them."""
    path = tmp_path / "checkpoint.pt"
    mapper = make_mapper()
    feed(mapper, FRAMES[:1])
    settings = {"num_classes": 2, "sdf": {"hidden_dim": 64}}
    old = {"_target_": "neuralfeels_sem.fields.semantic_field.SemanticField", "_convert_": "object"}
    save_checkpoint(path, mapper, frame_index=0, model_config={**old, "bound": 0.1, **settings})
    assert load_checkpoint(path, make_mapper(), model_config=settings)["frame_index"] == 0
    with pytest.raises(ConfigError, match="model.sdf"):
        load_checkpoint(path, make_mapper(), model_config={**settings, "sdf": {"hidden_dim": 32}})


def test_a_checkpoint_from_before_a_setting_existed_resumes_at_its_default(tmp_path) -> None:
    """model.material.grid_levels came later with default 0 (no grid), what older
    checkpoints ran; its default is 4 now, but they still resume at 0 and are refused with
    any other value."""
    path = tmp_path / "checkpoint.pt"
    mapper = make_mapper()
    feed(mapper, FRAMES[:1])
    older = {"num_classes": 2, "material": {"sh_degree": 3}}
    save_checkpoint(path, mapper, frame_index=0, model_config=older)
    now = {"num_classes": 2, "material": {"sh_degree": 3, "grid_levels": 0}}
    assert load_checkpoint(path, make_mapper(), model_config=now)["frame_index"] == 0
    with pytest.raises(ConfigError, match="model.material.grid_levels"):
        load_checkpoint(path, make_mapper(), model_config={**now, "material": {"grid_levels": 4}})
