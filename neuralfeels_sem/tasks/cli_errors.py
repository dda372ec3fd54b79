"""Hydra's own command-line errors in one line, exit code 2, as every other refusal.

A typo in a group, key or value (`objec=plushie`, `object=plushy`, `seed=abc`) fails while
Hydra composes the config, before any of this project's checks run. Hydra prints those
errors over several lines (the config search path, OmegaConf's `full_key` and
`object_type`, a hint about HYDRA_FULL_ERROR) and exits 1. `install` wraps Hydra's error
report so that these composition and override errors print as one line naming the key and
what to do, and exit 2; every other exception, and HYDRA_FULL_ERROR=1, keep Hydra's report.

It wraps `hydra._internal.utils.run_and_report`, the function every entry point of the
pinned hydra-core 1.3.8 (setup.py) runs its steps through; tests/tasks/test_cli_errors.py
runs the command line and fails if a Hydra upgrade moves it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from hydra._internal import utils as hydra_utils
from hydra.errors import ConfigCompositionException, OverrideParseException, SearchPathException
from omegaconf.errors import OmegaConfBaseException

EXIT_CODE = 2
COMPOSITION_ERRORS = (ConfigCompositionException, OverrideParseException, SearchPathException)
# OmegaConf's and Hydra's detail lines that name internals rather than the user's input.
_INTERNAL_LINES = ("full_key:", "object_type=", "reference_type=", "msg:")
HELP = "python run.py --help lists the groups, docs/configuration.md the keys"


def one_line(exc: BaseException) -> str:
    """`exc`'s message (with an OmegaConf cause's) as one line: the lines joined with '; ',
    an indented list (Hydra's available options) with ', ', internals dropped."""
    text = str(exc)
    if isinstance(exc.__cause__, OmegaConfBaseException):
        text += "\n" + str(exc.__cause__)
    text = text.split("Config search path:")[0]
    segments: list[list[str]] = []
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith(_INTERNAL_LINES):
            continue
        if line.startswith(("\t", "  ")) and segments and segments[-1][0].endswith(":"):
            segments[-1].append(stripped)  # an item of the list the previous line opened
        else:
            segments.append([stripped])
    joined = [head + (" " + ", ".join(items) if items else "") for head, *items in segments]
    line = "; ".join(part.rstrip(".") for part in joined)
    if isinstance(exc, OverrideParseException):  # the parser's message does not name it
        line = f"override {exc.override!r} does not parse: {line}"
    return line


def _report_in_one_line(original: Callable[[Callable[[], Any]], Any]) -> Callable:
    def run_and_report(func: Callable[[], Any]) -> Any:
        if hydra_utils._is_env_set("HYDRA_FULL_ERROR"):  # Hydra's own test of it
            return original(func)

        def guarded() -> Any:
            try:
                return func()
            except COMPOSITION_ERRORS as exc:
                print(f"error: {one_line(exc)} ({HELP})", file=sys.stderr, flush=True)
                sys.exit(EXIT_CODE)

        return original(guarded)

    run_and_report.wrapped = original  # type: ignore[attr-defined]
    return run_and_report


def install() -> None:
    """Report Hydra's composition errors in one line from now on (once per process)."""
    if not hasattr(hydra_utils.run_and_report, "wrapped"):
        hydra_utils.run_and_report = _report_in_one_line(hydra_utils.run_and_report)
