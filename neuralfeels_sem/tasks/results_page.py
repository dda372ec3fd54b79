"""Write the results page (docs/results.md) from run outputs, judged against today's defaults.

    python -m neuralfeels_sem.tasks.results_page --out docs/results.md [--readme README.md]
        [--bench bench.json] [--archive docs/results_data] DIR [DIR ...]

The page itself is built by eval/results_page.py. This wiring composes today's config for
each run's object, experiment, perception preset and config groups, so a run made before
a default changed is shown with the setting it ran with (eval/results_drift.py), not as
a default-config run. With --archive every source and bench report read is kept there
(the project's page uses docs/results_data/, eval/results_archive.py), and one whose
directory is gone is read from there, so the page can be regenerated from the repository
alone.
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
from neuralfeels_sem.eval.results_archive import (
    archived_bench,
    load_archived,
    save_bench,
    save_source,
)
from neuralfeels_sem.eval.results_drift import group_overrides
from neuralfeels_sem.eval.results_page import COMMAND, build_command, render, update_readme
from neuralfeels_sem.eval.results_runs import Run, Source, display_path, load_source
from neuralfeels_sem.utils.nested import flatten
from neuralfeels_sem.utils.paths import REPO_DIR

ARCHIVE_DIR = REPO_DIR / "docs" / "results_data"  # eval/results_archive.py


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


def source_of(path: Path, archive: Path | None) -> Source:
    """A run or sweep directory, archived on the way; where it is gone, its archived copy."""
    if archive is None or path.is_dir():
        source = load_source(path)
        if archive is not None:
            save_source(source, archive)
        return source
    kept = load_archived(path, archive)
    if kept is None:
        raise DataError(f"{path}: no such directory, and no copy of it in {archive}")
    return kept


def kept_bench(path: Path, archive: Path) -> Path:
    """A bench report to read: kept in the archive when it exists, else the archived copy."""
    if path.is_file():
        save_bench(path, archive)
        return path
    return archived_bench(path, archive)


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
    parser.add_argument(
        "--archive",
        type=Path,
        help="keep each source's page inputs here, and read a source from here where its "
        f"directory is gone (the project's: {display_path(ARCHIVE_DIR)})",
    )
    parser.add_argument("dirs", nargs="+", metavar="DIR", help="run or sweep directory")
    args = parser.parse_args(argv)
    archive = args.archive
    # A directory named twice (`sweep` and `sweep/`) would count its runs twice.
    dirs = list(dict.fromkeys(str(Path(d)) for d in args.dirs))
    benches = list(dict.fromkeys(args.bench))
    try:
        sources = against_today([source_of(Path(d), archive) for d in dirs])
        locate = (lambda p: p) if archive is None else (lambda p: kept_bench(p, archive))
        page = render(
            sources,
            build_command(args.out, dirs, benches, args.readme, archive),
            benches,
            locate,
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
