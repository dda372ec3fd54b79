"""Resuming across object, object content, sensor, classes or model is refused, in process."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import torch

from neuralfeels_sem.core.errors import ConfigError, DataError, UserError
from neuralfeels_sem.mapping.checkpoint import read_provenance
from neuralfeels_sem.mapping.provenance import Provenance, check_provenance
from tests.reliability.checks import write_run_dir

SAVED = Provenance(
    object_name="plushie",
    object_hash="ab12ab12ab12",
    sensor="sim",
    classes=("fabric", "plastic"),
    model={"sdf": {"hidden_dim": 64}, "material": {"concat_sdf_features": True}},
)

MISMATCHES = {
    "object": (
        replace(SAVED, object_name="patched_toy", object_hash="cd34cd34cd34"),
        ["plushie (hash ab12ab12ab12)", "patched_toy (hash cd34cd34cd34)", "object=plushie"],
    ),
    "object_content": (
        replace(SAVED, object_hash="ffffffffffff"),
        ["hash ab12ab12ab12", "hash ffffffffffff", "mesh or labels changed"],
    ),
    "sensor": (replace(SAVED, sensor="replay"), ["sensor sim", "is replay", "sensor=sim"]),
    "classes": (
        replace(SAVED, classes=("fabric", "plastic", "metal")),
        ["[fabric,plastic]", "[fabric,plastic,metal]", "materials=[fabric,plastic]"],
    ),
    "model": (
        replace(SAVED, model={**SAVED.model, "sdf": {"hidden_dim": 32}}),
        ["model.sdf.hidden_dim: 64 there, 32 here"],
    ),
    "model_key_added": (
        replace(SAVED, model={**SAVED.model, "extra": {"depth": 2}}),
        ["model.extra.depth: unset there, 2 here"],
    ),
}


@pytest.mark.parametrize("case", sorted(MISMATCHES))
def test_resume_across_a_difference_is_refused_naming_both_sides(case: str) -> None:
    current, names = MISMATCHES[case]
    with pytest.raises(ConfigError) as info:
        check_provenance(SAVED, current, "run/checkpoint.pt")
    message = str(info.value)
    assert "\n" not in message and message.startswith("mapping.resume=run/checkpoint.pt:")
    for name in names:
        assert name in message, (name, message)


def test_the_same_experiment_resumes() -> None:
    # Hydra's instantiate keys and `bound` are not model settings.
    current = replace(SAVED, model={**SAVED.model, "_target_": "x", "bound": 0.2})
    check_provenance(SAVED, current, "run/checkpoint.pt")


def test_a_checkpoint_records_its_provenance(tmp_path: Path) -> None:
    path = write_run_dir(tmp_path / "run", SAVED)
    assert read_provenance(path) == SAVED


def _truncated(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:200])


def _lacking_keys(path: Path) -> None:
    payload = torch.load(path, weights_only=True)
    del payload["mapper"]
    torch.save(payload, path)


def _version_1(path: Path) -> None:
    payload = torch.load(path, weights_only=True)
    payload["version"] = 1
    del payload["provenance"]
    torch.save(payload, path)


BAD_CHECKPOINTS = {
    "missing": (lambda p: p.unlink(), DataError, "does not exist"),
    "directory": (lambda p: (p.unlink(), p.mkdir()), DataError, "is a directory"),
    "truncated": (_truncated, DataError, "is unreadable"),
    "garbage": (lambda p: p.write_bytes(b"not a checkpoint"), DataError, "is unreadable"),
    "foreign": (lambda p: torch.save({"weights": 1}, p), DataError, "not a SemanticFeels"),
    "lacking_keys": (_lacking_keys, DataError, "lacks mapper"),
    "no_provenance": (_version_1, ConfigError, "records no object, sensor or classes"),
}


@pytest.mark.parametrize("case", sorted(BAD_CHECKPOINTS))
def test_a_bad_resume_file_is_named_in_one_line(tmp_path: Path, case: str) -> None:
    path = write_run_dir(tmp_path / "run", SAVED)
    damage, error, phrase = BAD_CHECKPOINTS[case]
    damage(path)
    with pytest.raises(UserError) as info:
        read_provenance(path)
    assert isinstance(info.value, error)
    assert "\n" not in str(info.value) and phrase in str(info.value)
    assert str(path) in str(info.value)
