"""The README and docs/*.md: every relative link resolves, and the README stays a front page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from neuralfeels_sem.utils.paths import REPO_DIR

README = REPO_DIR / "README.md"
# The READMEs shipped beside the networks (neuralfeels_sem/assets/<name>/README.md).
ASSET_READMES = sorted((REPO_DIR / "neuralfeels_sem" / "assets").glob("*/README.md"))
CHANGELOG = REPO_DIR / "CHANGELOG.md"
PAGES = [README, CHANGELOG, *sorted((REPO_DIR / "docs").glob("*.md")), *ASSET_READMES]
MAX_README_LINES = 250

LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")
CODE_SPAN = re.compile(r"`+[^`]*`+")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"")
EXTERNAL = ("http://", "https://", "mailto:", "ftp://")


def prose_lines(text: str) -> list[str]:
    """Lines outside fenced code blocks, with inline code spans removed."""
    lines, fenced = [], False
    for line in text.splitlines():
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            lines.append(CODE_SPAN.sub("", line))
    return lines


def links(page: Path) -> list[str]:
    return [m.group(1) for line in prose_lines(page.read_text()) for m in LINK.finditer(line)]


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link keeps its text
    text = re.sub(r"[^\w\- ]", "", text.lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    found: set[str] = set()
    seen: dict[str, int] = {}
    text = page.read_text()
    fenced = False
    for line in text.splitlines():
        if FENCE.match(line):
            fenced = not fenced
            continue
        if fenced:
            continue
        match = HEADING.match(line)
        if match:
            base = slug(match.group(2))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f"{base}-{count}")
        found.update(HTML_ANCHOR.findall(line))
    return found


def test_readme_is_a_front_page() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines (at most 250)"
    assert "docs/results.md" in README.read_text()


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO_DIR)))
def test_relative_links_resolve(page: Path) -> None:
    broken = []
    for target in links(page):
        if target.startswith(EXTERNAL):
            continue
        path_part, _, anchor = target.partition("#")
        resolved = (page.parent / path_part).resolve() if path_part else page
        if not resolved.exists():
            broken.append(f"{target} (no {resolved})")
        elif anchor and resolved.suffix == ".md" and anchor not in anchors(resolved):
            broken.append(f"{target} (no heading or anchor #{anchor} in {resolved.name})")
    assert not broken, f"{page.name}: broken links: {broken}"


def test_the_link_checker_sees_links_and_skips_code(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "# A title: `with code`\n"
        'See [this](other.md#a-title-with-code) and ![pic](images/x.png "t").\n'
        "`[not a link](nowhere.md)`\n"
        "```\n[nor this](gone.md)\n```\n"
        "[web](https://example.org)\n"
    )
    assert links(page) == ["other.md#a-title-with-code", "images/x.png", "https://example.org"]
    assert anchors(page) == {"a-title-with-code"}


# ---------------------------------------------------------------------------- measured figures
# Measured figures live on the generated results page (docs/results.md, and the README's
# table between its markers); other pages link to them. These patterns catch what a page
# would carry if someone pasted measurements back in; definitions, settings and sizes of
# shipped assets do not match them.
GENERATED_PAGES = {"results.md"}
DECIMAL_CELL = re.compile(r"^\**[+-]?\d+\.\d+")
DECIMAL_PERCENT = re.compile(r"\b\d+\.\d+\s*%")
PROSE_FIGURES = {
    "a mean ± std": re.compile(r"\d\s*±\s*\d"),
    "a measured rate": re.compile(
        r"\b\d+\.\d+\s*(?:steps/s|frames/s|img/s|images/s|ms/frame|s/frame|ms per frame)"
    ),
    "a load average": re.compile(r"\bload(?: average)?(?: of| about| between)? \d"),
}
# An asset README describes a recipe and links to the results page for its figures; it
# has no definition that needs a decimal percentage (docs pages do: 100 / 3 = 33.3 %).
ASSET_PROSE_FIGURES = {"a decimal percentage": DECIMAL_PERCENT}
# Tables of properties of shipped assets, known by a column of their header.
ASSET_TABLE_COLUMNS = ("| size (cm) |",)
README_TABLE_MARKERS = ("<!-- results-table:", "<!-- results-table end")


def outside_generated_table(lines: list[str]) -> list[str]:
    """The lines of a page without the README's generated results table."""
    kept, inside = [], False
    for line in lines:
        if line.startswith(README_TABLE_MARKERS[0]):
            inside = True
        elif line.startswith(README_TABLE_MARKERS[1]):
            inside = False
        elif not inside:
            kept.append(line)
    return kept


def measured_figures(text: str, prose_figures: dict[str, re.Pattern] = PROSE_FIGURES) -> list[str]:
    """Lines of a page that carry measured figures: a table row with a decimal percentage
    or two decimal cells (outside settings tables, whose header names a default), or one
    of `prose_figures` in prose (by default a mean ± std, a measured rate or a load
    average)."""
    found, header = [], None
    for line in outside_generated_table(prose_lines(text)):
        if not line.strip().startswith("|"):
            header = None
            found += [
                f"{why}: {line.strip()}" for why, p in prose_figures.items() if p.search(line)
            ]
            continue
        if header is None:
            header = line.strip()
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        settings = "default" in header.lower() or any(c in header for c in ASSET_TABLE_COLUMNS)
        decimals = sum(bool(DECIMAL_CELL.match(c)) for c in cells)
        if not settings and (decimals >= 2 or DECIMAL_PERCENT.search(line)):
            found.append(f"table row: {line.strip()}")
    return found


@pytest.mark.parametrize(
    "page",
    [p for p in PAGES if p.name not in GENERATED_PAGES],
    ids=lambda p: str(p.relative_to(REPO_DIR)),
)
def test_measured_figures_live_on_the_results_page(page: Path) -> None:
    patterns = PROSE_FIGURES | (ASSET_PROSE_FIGURES if page in ASSET_READMES else {})
    found = measured_figures(page.read_text(), patterns)
    assert not found, (
        f"{page.name} quotes measured figures; generate them on docs/results.md "
        f"(eval/results_*.py) and link there: {found[:3]}"
    )


def test_the_figure_check_flags_pasted_measurements_and_spares_definitions() -> None:
    measured = (
        "| object | seed | pose error mm | mean-class % |\n|---|---|---|---|\n"
        "| `patchwork` | 0 | 11.9 / 14.7 | 80.5 |\n\n"
        "| part | loop share |\n|---|---|\n| sim rendering | 7.5 % |\n\n"
        "It ran at 13.6 frames/s (load average 1) and scored 87.2 ± 1.2.\n"
    )
    found = measured_figures(measured)
    assert [f.split(":")[0] for f in found] == [
        "table row",
        "table row",
        "a mean ± std",
        "a measured rate",
        "a load average",
    ]
    definitions = (
        "| key | default | meaning |\n|---|---|---|\n| `blur_px` | 0.8, 1.6 | smoothing |\n\n"
        "Four fingers at 10 Hz need 40 images/s; a confidence of 0.8 is right 80 % of the time.\n"
        "```\n| a | 1.5 | 2.5 |\n```\n"
        f"{README_BEGIN_LINE}\n| `plushie` | 84.8 ± 3.6 | 50.0 |\n{README_END_LINE}\n"
    )
    assert measured_figures(definitions) == []


def test_asset_readmes_are_checked_and_may_not_quote_percentages_in_prose() -> None:
    assert {p.parent.name for p in ASSET_READMES} >= {"classifier", "tactile_depth"}
    prose = "Trained in rounds; the test split scores 97.70 %, centred 99.81 % (see results).\n"
    assert measured_figures(prose) == []
    found = measured_figures(prose, PROSE_FIGURES | ASSET_PROSE_FIGURES)
    assert [f.split(":")[0] for f in found] == ["a decimal percentage"]
    recipe = "The test split is 15 % of the data; lr 3e-4, 24 epochs, 0.2-1.3 mm textures.\n"
    assert measured_figures(recipe, PROSE_FIGURES | ASSET_PROSE_FIGURES) == []


README_BEGIN_LINE = (
    "<!-- results-table: generated by eval/results_page.py --readme; do not edit -->"
)
README_END_LINE = "<!-- results-table end -->"
