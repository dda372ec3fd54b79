"""Hydra's own errors (a typo in a group, key, value or override) in one line, exit 2."""

from __future__ import annotations

import pytest
from hydra.errors import ConfigCompositionException, MissingConfigException
from omegaconf.errors import ConfigKeyError

from neuralfeels_sem.tasks.cli_errors import one_line
from tests.helpers import run_cli
from tests.reliability.checks import assert_refused

SLOW = pytest.mark.slow  # each case is one start of run.py; three run by default


def test_a_list_of_options_joins_into_one_line_without_the_search_path() -> None:
    exc = MissingConfigException(
        "In 'config': Could not find 'object/plushy'\n\nAvailable options in 'object':\n"
        "\tpatchwork\n\tplushie\nConfig search path:\n\tprovider=hydra, path=pkg://hydra.conf"
    )
    assert one_line(exc) == (
        "In 'config': Could not find 'object/plushy'; "
        "Available options in 'object': patchwork, plushie"
    )


def test_omegaconf_cause_kept_and_its_internals_dropped() -> None:
    cause = ConfigKeyError(
        "Key 'objec' not in 'RootConfig'\n    full_key: objec\n    object_type=RootConfig"
    )
    exc = ConfigCompositionException("Could not override 'objec'.\nTo append use +objec=x")
    exc.__cause__ = cause
    assert one_line(exc) == (
        "Could not override 'objec'; To append use +objec=x; Key 'objec' not in 'RootConfig'"
    )


@pytest.mark.parametrize(
    "args, names",
    [
        pytest.param(["objec=plushie"], ["'objec'", "+objec=plushie"], id="unknown_key"),
        pytest.param(["object=plushy"], ["object/plushy", "plastic_toy, plushie"], id="option"),
        pytest.param(["seed=["], ["override 'seed=[' does not parse"], id="bad_syntax"),
        pytest.param(
            ["seed=abc"], ["seed=abc", "converted to Integer"], id="bad_value", marks=SLOW
        ),
        pytest.param(
            ["-m", "seed=0,1", "sensor.duration_s=abc"], ["duration_s=abc"], id="sweep", marks=SLOW
        ),
    ],
)
def test_hydra_refuses_in_one_line_with_exit_code_2(tmp_path, args, names) -> None:
    result = run_cli([*args, f"hydra.run.dir={tmp_path / 'run'}"], timeout=120)
    assert_refused(result, 2, *names, "--help lists the groups")
    assert not (tmp_path / "run").exists()
