"""The package's layers, read from its imports (function-level and type-only ones too).

Floors, lowest first: config (the reader and every section's dataclass) → env and
hypergraph → policies → evaluation → oracle ∥ population →
methods → experiment → the commands (`hola_ray.commands`, with `hola_ray.run` and
`hola_ray.__main__` their entries; flight beside oracle and population). A package imports
only packages on lower floors, plus the shared helpers (`cli`, `clock`, `homes`,
`interrupt`, `process`, `progress`, `provenance`, `third_party`); no package imports a
command; no two modules import each other, directly or round a longer circle. The root also
holds `ray_worker`, the script a local Ray's workers run.

`KNOWN` lists the upward imports that are still there. A new one fails this test, and so
does an entry that is gone (strike it from the list).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "hola_ray"

FLOORS = {
    "config": 0,
    "env": 1,
    "hypergraph": 1,
    "policies": 2,
    "evaluation": 3,
    "oracle": 4,
    "population": 4,
    "flight": 4,
    "methods": 5,
    "experiment": 6,
}
"""Package → floor; a package imports only packages on lower floors."""

SHARED = {"cli", "clock", "homes", "interrupt", "process", "progress", "provenance", "third_party"}
"""Top-level helper modules any package may import."""

KNOWN: set[tuple[str, str]] = set()
"""Upward imports not yet removed (none: keep it empty)."""


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports() -> dict[str, set[str]]:
    """Module → the hola_ray modules it imports anywhere in its file."""
    modules = {module_name(p): p for p in ROOT.rglob("*.py")}
    out: dict[str, set[str]] = {}
    for name, path in modules.items():
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name.startswith("hola_ray"))
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                if not node.module.startswith("hola_ray"):
                    continue
                # `from hola_ray.x import y` names module x.y when that is a module
                subs = {f"{node.module}.{a.name}" for a in node.names}
                found.update(subs & modules.keys() or {node.module})
        out[name] = found - {name}
    return out


def place(module: str) -> str:
    """'env', 'policies', … for a package module; the module's own name at the top level."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "hola_ray"


def upward(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    bad = set()
    for source, targets in graph.items():
        home = place(source)
        if home not in FLOORS:
            continue  # a command module or a shared helper: may import packages
        for target in targets:
            there = place(target)
            if there == home or there in SHARED:
                continue
            if there not in FLOORS or FLOORS[there] >= FLOORS[home]:
                bad.add((source, target))
    return bad


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import graph's strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_reader_sees_function_level_and_type_only_imports():
    graph = imports()
    # function-level (inside `validation_teammates`) and module-level imports both count
    assert "hola_ray.evaluation.pools" in graph["hola_ray.methods.monitors"]
    assert "hola_ray.env.trajectory" in graph["hola_ray.env.render"]  # under TYPE_CHECKING
    assert upward({"hola_ray.env.render": {"hola_ray.evaluation.trajectory"}}) == {
        ("hola_ray.env.render", "hola_ray.evaluation.trajectory")
    }
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_runs_up_a_floor_beyond_the_known_ones():
    bad = upward(imports())
    assert bad - KNOWN == set(), "new upward imports"
    assert KNOWN - bad == set(), "gone: strike them from KNOWN"


def test_no_package_imports_a_command_module():
    graph = imports()
    # the package root holds the shared helpers, the commands' two entries and the entry of
    # a local Ray's workers, no command
    root = {m for m in graph if m.count(".") == 1 and place(m) not in {*FLOORS, "commands"}}
    entries = {"hola_ray.run", "hola_ray.__main__", "hola_ray.ray_worker"}
    assert root - {f"hola_ray.{s}" for s in SHARED} == entries
    commands = {m for m in graph if place(m) == "commands"} | root
    commands -= {f"hola_ray.{s}" for s in SHARED}
    assert "hola_ray.commands.run" in commands and "hola_ray.run" in commands
    for source, targets in graph.items():
        if place(source) in FLOORS:
            assert not targets & commands, (source, targets & commands)


def test_no_circles():
    assert circles(imports()) == []
