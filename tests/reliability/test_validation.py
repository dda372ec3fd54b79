"""Bad input is refused before any heavy set-up, in one line naming the key and the fix.

In-process cases call the checks run.py's guard runs first (configs.validate_config, then
tasks/preflight.py) on a composed config; a handful of command-line cases check the whole
path: exit code 2, one stderr line, no traceback, nothing written, and the files named on
the command line unchanged.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.configs import validate_config
from neuralfeels_sem.core.errors import UserError
from neuralfeels_sem.tasks.preflight import check_table_memory, hash_table_bytes, preflight
from tests.helpers import compose_config, run_cli
from tests.reliability.checks import assert_refused, tree_digest

# case -> (overrides, words the one-line error holds)
CONFIG_CASES: dict[str, tuple[list[str], list[str]]] = {
    "plus_mapping_key": (["+mapping.foo=1"], ["unknown key mapping.foo"]),
    "plus_sensor_typo": (
        ["+sensor.duraton_s=2"],
        ["unknown key sensor.duraton_s", "did you mean sensor.duration_s?"],
    ),
    "plus_root_key": (["+foo=1"], ["unknown key foo"]),
    "plus_nested_typo": (
        ["+model.sdf.hiden_dim=3"],
        ["unknown key model.sdf.hiden_dim", "did you mean model.sdf.hidden_dim?"],
    ),
    "plus_mapper_typo": (
        ["+mapping.mapper.steps_per_frme=3"],
        ["did you mean mapping.mapper.steps_per_frame?"],
    ),
    "duration_nan": (["sensor.duration_s=nan"], ["sensor.duration_s=nan", "finite"]),
    "duration_inf": (["sensor.duration_s=inf"], ["sensor.duration_s=inf", "finite"]),
    "duration_1e12": (["sensor.duration_s=1e12"], ["sensor.duration_s=1000000000000.0", "86400"]),
    "duration_real_nan": (
        ["sensor=real", "sensor.duration_s=nan"],
        ["sensor.duration_s=nan", "finite"],
    ),
    "record_duration_inf": (
        ["task=record", "task.duration_s=inf"],
        ["task.duration_s=inf", "finite"],
    ),
    "fps_nan": (["sensor.fps=nan"], ["sensor.fps=nan", "finite rate"]),
    "fps_1e9": (["sensor.fps=1e9"], ["sensor.fps=1000000000.0", "1000] Hz"]),
    "seed_beyond_64_bits": (["seed=18446744073709551616"], ["seed=18446744073709551616"]),
    "seed_beyond_32_bits": (["seed=4294967296"], ["seed=4294967296", "2^32 - 1"]),
    "seed_negative": (["seed=-1"], ["seed=-1"]),
    "on_damaged_frame_unknown": (
        ["sensor=replay", "sensor.on_damaged_frame=ignore"],
        ["sensor.on_damaged_frame='ignore'", "skip or stop"],
    ),
}


def _one_line(exc: BaseException, words: list[str]) -> None:
    message = str(exc)
    assert exc.exit_code == 2 and "\n" not in message, message
    for word in words:
        assert word in message, (word, message)


@pytest.mark.parametrize("case", list(CONFIG_CASES))
def test_config_refused_by_the_schema_checks(case: str) -> None:
    overrides, words = CONFIG_CASES[case]
    with pytest.raises(UserError) as caught:
        validate_config(compose_config(overrides))
    _one_line(caught.value, words)


def _nan_mesh(tmp: Path) -> str:
    path = tmp / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    return str(path)


def _huge_mesh(tmp: Path) -> str:
    """A binary STL of 200,001 triangles (MuJoCo takes 200,000)."""
    count = 200_001
    path = tmp / "huge.stl"
    triangles = np.zeros((count, 12), np.float32)
    triangles[:, 3:] = np.random.default_rng(0).random((count, 9), np.float32)
    records = np.zeros(count, dtype=[("data", "<f4", (12,)), ("attr", "<u2")])
    records["data"] = triangles
    path.write_bytes(b"\0" * 80 + struct.pack("<I", count) + records.tobytes())
    return str(path)


def _garbage(tmp: Path, name: str) -> str:
    (tmp / name).write_bytes(b"\x80\x04 not what it claims to be" * 8)
    return str(tmp / name)


def _feelsight_without_depth(tmp: Path) -> str:
    """A FeelSight log folder holding data.pkl but no realsense/<camera>/depth.npz."""
    _garbage(tmp, "data.pkl")
    return str(tmp)


def _recording_with_truncated_meta(tmp: Path) -> str:
    (tmp / "rec").mkdir()
    (tmp / "rec" / "meta.json").write_text('{"schema_version": 1, "clas')
    (tmp / "rec" / "frames.jsonl").write_text("")
    return str(tmp / "rec")


# case -> (overrides from a scratch folder, words the one-line error holds)
PREFLIGHT_CASES: dict[str, Callable[[Path], tuple[list[str], list[str]]]] = {
    "classifier_weights_on_map": lambda t: (
        [f"classifier.weights={t / 'b0.pth'}"],
        ["classifier.weights=", "task=map would ignore it", "classifier.checkpoint"],
    ),
    "recording_missing": lambda t: (
        ["sensor=replay", f"sensor.recording={t / 'nope'}"],
        ["recording", "not found", "sensor.recording"],
    ),
    "recording_not_a_recording": lambda t: (
        ["sensor=replay", f"sensor.recording={t}"],
        ["is not a recording", "sensor.recording"],
    ),
    "recording_meta_truncated": lambda t: (
        ["sensor=replay", f"sensor.recording={_recording_with_truncated_meta(t)}"],
        ["meta.json is damaged"],
    ),
    "feelsight_log_missing": lambda t: (
        ["sensor=replay", "sensor.format=feelsight", f"sensor.recording={t}"],
        ["is not a FeelSight log"],
    ),
    "feelsight_depth_missing": lambda t: (
        [
            "sensor=replay",
            "sensor.format=feelsight",
            f"sensor.recording={_feelsight_without_depth(t)}",
        ],
        ["realsense/front-left/depth.npz is missing", "sensor.camera"],
    ),
    "classifier_checkpoint_missing": lambda t: (
        [f"classifier.checkpoint={t / 'nope.pt'}"],
        ["classifier.checkpoint=", "does not exist"],
    ),
    "classifier_checkpoint_is_dir": lambda t: (
        [f"classifier.checkpoint={t}"],
        ["classifier.checkpoint=", "is a directory"],
    ),
    "classifier_checkpoint_garbage": lambda t: (
        [f"classifier.checkpoint={_garbage(t, 'c.pt')}"],
        ["classifier checkpoint", "is not readable"],
    ),
    "depth_checkpoint_missing": lambda t: (
        [f"mapping.mapper.tactile_depth.checkpoint={t / 'nope.pt'}"],
        ["mapping.mapper.tactile_depth.checkpoint=", "does not exist"],
    ),
    "depth_checkpoint_garbage": lambda t: (
        [f"mapping.mapper.tactile_depth.checkpoint={_garbage(t, 'd.pt')}"],
        ["tactile depth checkpoint", "is not readable"],
    ),
    "mesh_missing": lambda t: (
        ["object=custom", f"object.mesh={t / 'nope.obj'}"],
        ["object.mesh=", "does not exist"],
    ),
    "mesh_is_dir": lambda t: (
        ["object=custom", f"object.mesh={t}"],
        ["object.mesh=", "is a directory"],
    ),
    "mesh_garbage_stl": lambda t: (
        ["object=custom", f"object.mesh={_garbage(t, 'g.stl')}"],
        ["object.mesh=", "is unreadable", "re-export"],
    ),
    "mesh_nan_vertices": lambda t: (
        ["object=custom", f"object.mesh={_nan_mesh(t)}"],
        ["1 vertices that are NaN or infinite"],
    ),
    "mesh_over_mujoco_faces": lambda t: (
        ["object=custom", f"object.mesh={_huge_mesh(t)}"],
        ["200001 faces", "MuJoCo's 200000", "decimate"],
    ),
    "labels_missing": lambda t: (
        ["object=custom", f"object.labels={t / 'nope.npy'}"],
        ["object.labels=", "does not exist"],
    ),
}


@pytest.mark.parametrize("case", list(PREFLIGHT_CASES))
def test_files_and_settings_refused_before_set_up(tmp_path: Path, case: str) -> None:
    overrides, words = PREFLIGHT_CASES[case](tmp_path)
    cfg = compose_config(overrides)
    validate_config(cfg)  # the schema accepts it: the file or the task is the problem
    before = tree_digest(tmp_path)
    with pytest.raises(UserError) as caught:
        preflight(cfg)
    _one_line(caught.value, words)
    assert tree_digest(tmp_path) == before


def test_the_hash_table_is_checked_against_memory() -> None:
    cfg = compose_config(["model.encoding.log2_table_size=24"])
    need = hash_table_bytes(cfg.model.encoding)
    check_table_memory(cfg, available=need)  # fits exactly
    with pytest.raises(UserError) as caught:
        check_table_memory(cfg, available=need - 1)
    _one_line(caught.value, ["model.encoding.log2_table_size=24", "=23 or less"])


def test_the_table_estimate_is_the_fields_table() -> None:
    """Rows as HashGridEncoding builds them, in float32, with Adam's two moments."""
    from neuralfeels_sem.fields.hash_grid import HashGridConfig, HashGridEncoding

    cfg = compose_config(["model.encoding.log2_table_size=12"])
    table = HashGridEncoding(HashGridConfig(log2_table_size=12)).table
    assert hash_table_bytes(cfg.model.encoding) == table.numel() * 4 * 3


def test_shipped_configs_pass_the_checks() -> None:
    """The defaults, and a replay config without a recording yet, are not refused early."""
    cfg = compose_config([])
    validate_config(cfg)
    preflight(cfg)


# A handful through the command line: exit 2, one line, no traceback, nothing written.
CLI_CASES = {
    "plus_key": (["+mapping.foo=1"], ["unknown key mapping.foo"]),
    "duration_nan": (["sensor.duration_s=nan"], ["sensor.duration_s=nan"]),
    "classifier_weights_on_map": (["classifier.weights=b0.pth"], ["classifier.weights=b0.pth"]),
    "table_too_large": (
        ["model.encoding.log2_table_size=30"],
        ["model.encoding.log2_table_size=30 needs", "is available"],
    ),
}


CLI_PARAMS = [
    pytest.param(name, id=name, marks=() if name == "plus_key" else pytest.mark.slow)
    for name in CLI_CASES
]


@pytest.mark.parametrize("case", CLI_PARAMS)
def test_command_line_refusal(tmp_path: Path, case: str) -> None:
    args, words = CLI_CASES[case]
    run_dir = tmp_path / "run"
    result = run_cli([*args, f"hydra.run.dir={run_dir}"], timeout=120)
    assert_refused(result, 2, *words)
    assert not run_dir.exists()


@pytest.mark.slow
def test_a_sweep_job_refused_by_preflight_writes_error_txt(tmp_path: Path) -> None:
    """In a sweep the same checks run per job (tasks/runner.py): each refused job leaves
    its one line in error.txt and the sweep goes on to the end."""
    sweep = tmp_path / "sweep"
    result = run_cli(
        ["-m", "task=info", "classifier.weights=a.pth,b.pth", f"hydra.sweep.dir={sweep}"],
        timeout=300,
    )
    assert "Traceback" not in result.stderr + result.stdout
    errors = sorted(sweep.glob("*/error.txt"))
    assert len(errors) == 2
    for path in errors:
        lines = path.read_text().splitlines()
        assert len(lines) == 1 and "task=info would ignore it" in lines[0]
