"""Write the results page (docs/results.md) from run outputs, judged against today's defaults.

    python -m neuralfeels_sem.tasks.results_page --out docs/results.md [--readme README.md]
        [--bench bench.json] DIR [DIR ...]

The page itself is built by eval/results_page.py. This wiring composes today's config for
each run's object, experiment, perception preset and config groups, so a run made before
a default changed is shown with the setting it ran with (eval/results_drift.py), not as
a default-config run.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from hydra import compose, initialize_config_dir
from hydra.errors import HydraException
from omegaconf import OmegaConf

from neuralfeels_sem.configs import register_configs
from neuralfeels_sem.core.errors import DataError, UserError
from neuralfeels_sem.eval.results_drift import group_overrides
from neuralfeels_sem.eval.results_page import COMMAND, build_command, render, update_readme
from neuralfeels_sem.eval.results_runs import Run, Source, load_source
from neuralfeels_sem.utils.nested import flatten
from neuralfeels_sem.utils.paths import REPO_DIR


def defaults_composer() -> Callable[[tuple[str, ...]], dict | None]:
    """compose(overrides) -> today's config, flattened and unresolved (None when the
    overrides no longer compose, e.g. an option removed since the run); cached."""
    register_configs()
    cache: dict[tuple[str, ...], dict | None] = {}

    def today(overrides: tuple[str, ...]) -> dict | None:
        if overrides not in cache:
            try:
                cfg = compose(config_name="config", overrides=list(overrides))
                cache[overrides] = flatten(OmegaConf.to_container(cfg, resolve=False))
            except HydraException:
                cache[overrides] = None
        return cache[overrides]

    return today


def against_today(sources: Sequence[Source]) -> list[Source]:
    """The sources with each run's `today` set (runs without a recorded config keep None)."""
    with initialize_config_dir(config_dir=str(REPO_DIR / "conf"), version_base="1.3"):
        today = defaults_composer()

        def judged(run: Run) -> Run:
            if run.config is None:
                return run
            return dataclasses.replace(
                run, today=today(tuple(group_overrides(run.overrides, run.config)))
            )

        return [dataclasses.replace(s, runs=[judged(r) for r in s.runs]) for s in sources]


def write(text: str, out: Path) -> None:
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    except OSError as exc:
        raise DataError(f"{out}: cannot write ({exc.strerror})") from None


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog=COMMAND, description="Write the results page from run and sweep directories."
    )
    parser.add_argument("--out", type=Path, help="markdown file to write (default: stdout)")
    parser.add_argument(
        "--readme", type=Path, help="also rewrite this README's results table (between markers)"
    )
    parser.add_argument(
        "--bench",
        type=Path,
        action="append",
        default=[],
        help="a `make bench` report (bench.json) for the speed section; repeat for reports "
        "from other machines (one with a GPU)",
    )
    parser.add_argument("dirs", nargs="+", metavar="DIR", help="run or sweep directory")
    args = parser.parse_args(argv)
    try:
        sources = against_today([load_source(Path(d)) for d in args.dirs])
        page = render(
            sources, build_command(args.out, args.dirs, args.bench, args.readme), args.bench
        )
        if args.out is None:
            sys.stdout.write(page)
        else:
            write(page, args.out)
            runs = sum(len(s.runs) for s in sources)
            print(f"wrote {args.out} ({runs} runs from {len(sources)} directories)")
        if args.readme is not None:
            update_readme(args.readme, sources)
            print(f"rewrote the results table of {args.readme}")
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    return 0


if __name__ == "__main__":
    sys.exit(main())
