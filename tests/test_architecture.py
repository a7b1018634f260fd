"""The package's structure as docs/ARCHITECTURE.md draws it: layers that import only downwards, no
import cycle between modules, no module over 700 lines."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("openreloc_bench", "generators", "baselines")
MAX_LINES = 700

LAYERS = {
    "core": 0,  # geometry, config, errors, data, methods, vision, ...: every other top-level module
    "openreloc": 1,
    "baselines": 1,
    "generators": 1,
    "harness": 2,
    "envs": 3,
    "commands": 4,
    "cli": 5,
}
"""A module may import its own layer's and lower layers' modules; methods and the generator are peers
that never import each other."""


def modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join(parts)] = path
    return found


MODULES = modules()


def layer(module: str) -> str:
    parts = module.split(".")
    if parts[0] != "openreloc_bench":
        return parts[0]
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else "core"


def imported(module: str, path: Path) -> set[str]:
    """The project modules ``module`` imports, at the top or inside functions."""
    found = set()
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            # ``from package import submodule`` needs the submodule; any other name comes from ``base``
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in MODULES:
                name = name.rpartition(".")[0]
            if name and name != module and name not in PACKAGES:
                found.add(name)
    return found


IMPORTS = {m: imported(m, p) for m, p in MODULES.items()}


def test_layers_import_only_downwards() -> None:
    upward = [
        f"{m} ({layer(m)}) imports {n} ({layer(n)})"
        for m, names in IMPORTS.items()
        for n in names
        if LAYERS[layer(n)] > LAYERS[layer(m)] or (LAYERS[layer(n)] == LAYERS[layer(m)] and layer(n) != layer(m))
    ]
    assert not upward, "\n".join(upward)


def test_no_import_cycle() -> None:
    """Packages count as modules: a module importing its own package's ``__init__``, which imports it back,
    is a cycle too."""
    graph = nx.DiGraph((m, n) for m, names in IMPORTS.items() for n in names)
    cycles = [" -> ".join([*c, c[0]]) for c in nx.simple_cycles(graph)]
    assert not cycles, "\n".join(cycles)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_module_over_700_lines(module: str) -> None:
    lines = len(MODULES[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"{module} has {lines} lines: split it by concern"
