"""Imports point down the layer order of docs/design.md ("Package layout"), never up.

Every module of the package (and run.py) is parsed, not imported: each `import
neuralfeels_sem.X` or `from neuralfeels_sem.X import ...`, at the top or inside a
function, must name the module's own package or one in a lower layer. Packages in the
same layer are independent of each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from neuralfeels_sem.utils.paths import PACKAGE_DIR, REPO_DIR

# Bottom first. A package may import its own modules and those of any lower layer.
LAYERS: list[tuple[str, ...]] = [
    ("core",),  # frame types, hand and DIGIT conventions, geometry, materials, palette, errors
    ("utils",),  # paths, device, seeding
    ("objects", "fields", "perception"),  # object library; neural field; touch and vision
    ("sim", "mapping"),  # the simulator; the online mapper
    ("sensors",),  # Sensor interface and backends (sim/ wraps the simulator)
    ("eval",),  # scores a field against an object
    ("viz",),  # pictures of what eval measured
    ("pipeline",),  # runs across the layers (the mapping session), built from objects
    ("configs",),  # Hydra schemas: registers the configs that live beside their classes
    ("tasks",),  # wiring: compose config -> instantiate -> call (+ runner, callbacks)
    ("bench",),  # benchmarks and rig diagnostics
    ("run",),  # run.py, the entry point
]
LAYER = {name: rank for rank, names in enumerate(LAYERS) for name in names}

# Hardware and recordings never depend on the simulator: a rig without MuJoCo or pyrender
# must be able to run sensor=real and sensor=replay.
FORBIDDEN = {
    "neuralfeels_sem.sensors.real": ("neuralfeels_sem.sim", "neuralfeels_sem.sensors.sim"),
    "neuralfeels_sem.sensors.replay": ("neuralfeels_sem.sim", "neuralfeels_sem.sensors.sim"),
    "neuralfeels_sem.sensors.sim": (
        "neuralfeels_sem.sensors.real",
        "neuralfeels_sem.sensors.replay",
    ),
}

# Modules beside the packages, and their layer: only the package's __init__ (no imports).
TOP_LEVEL_MODULES = {"__init__": "core"}

ALLOWED: set[tuple[str, str]] = set()  # (importing module, imported module): none needed


def _modules() -> list[tuple[str, Path]]:
    found = [
        (".".join(p.relative_to(REPO_DIR).with_suffix("").parts), p)
        for p in sorted(PACKAGE_DIR.rglob("*.py"))
    ]
    return [*found, ("run", REPO_DIR / "run.py")]


def _layer_name(module: str) -> str:
    parts = module.split(".")
    if parts[0] == "run":
        return "run"
    if len(parts) == 1:
        return "core"  # neuralfeels_sem itself (its __init__)
    if parts[1] in TOP_LEVEL_MODULES:
        return TOP_LEVEL_MODULES[parts[1]]
    return parts[1]


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _imports(path: Path) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.ImportFrom):
            found.append((node.lineno, f"<relative import, level {node.level}>"))
        elif isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
    return [(line, m) for line, m in found if m.split(".")[0] in ("neuralfeels_sem", "<relative")]


def test_every_package_has_a_layer() -> None:
    packages = {p.name for p in PACKAGE_DIR.iterdir() if (p / "__init__.py").is_file()}
    modules = {p.stem for p in PACKAGE_DIR.glob("*.py")}
    assert packages - LAYER.keys() == set(), "place the new package in LAYERS and docs/design.md"
    assert modules - TOP_LEVEL_MODULES.keys() == set(), "put the module in a package"


@pytest.mark.parametrize("module, path", _modules(), ids=[m for m, _ in _modules()])
def test_imports_point_down(module: str, path: Path) -> None:
    own = _layer_name(module)
    bad = []
    for line, target in _imports(path):
        where = f"{path.relative_to(REPO_DIR)}:{line} imports {target}"
        if target.startswith("<relative"):
            bad.append(f"{where} (use absolute imports)")
            continue
        other = _layer_name(target)
        if other not in LAYER:
            bad.append(f"{where}: {other} has no layer")
        elif other != own and LAYER[other] >= LAYER[own] and (module, target) not in ALLOWED:
            bad.append(f"{where}: {other} is not below {own}")
        for prefix, banned in FORBIDDEN.items():
            hit = next((b for b in banned if _within(target, b)), None)
            if _within(module, prefix) and hit:
                bad.append(f"{where}: {prefix} must not import {hit}")
    assert not bad, "imports that point up the layer order:\n" + "\n".join(bad)
