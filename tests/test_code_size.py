"""Small files with one job, functions that fit on a screen (issue #23's limits).

A module may exceed MAX_MODULE_LINES and a function MAX_FUNCTION_LINES only with a
comment `# size: <why>` on its first line (the module's first line, the def line).
"""

from __future__ import annotations

import ast
from pathlib import Path

from neuralfeels_sem.utils.paths import REPO_DIR

MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60
SOURCES = sorted((REPO_DIR / "neuralfeels_sem").rglob("*.py")) + [REPO_DIR / "run.py"]


def excused(line: str) -> bool:
    return "# size:" in line


def oversized_functions(path: Path) -> list[str]:
    text = path.read_text()
    lines = text.splitlines()
    found = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            first = node.decorator_list[0].lineno if node.decorator_list else node.lineno
            length = node.end_lineno - first + 1
            if length > MAX_FUNCTION_LINES and not excused(lines[node.lineno - 1]):
                found.append(
                    f"{path.relative_to(REPO_DIR)}:{node.lineno} {node.name} ({length} lines)"
                )
    return found


def test_no_module_is_over_the_limit() -> None:
    over = [
        f"{p.relative_to(REPO_DIR)} ({n} lines)"
        for p in SOURCES
        if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
        and not excused(p.read_text().split("\n", 1)[0])
    ]
    assert not over, f"split these modules (max {MAX_MODULE_LINES} lines): {over}"


def test_no_function_is_over_the_limit() -> None:
    over = [f for p in SOURCES for f in oversized_functions(p)]
    assert not over, f"split these functions (max {MAX_FUNCTION_LINES} lines): {over}"
