"""The import graph of ``schemas/``, ``tasks/`` and ``flows/``, read statically (ast), points down only.

Layers, lowest first: ``schemas`` (contracts), ``tasks`` (stage maths and IO at the edges), ``flows``
(Prefect wrappers, caching, the flows and the command line). A module imports its own layer or a lower one.
Within ``tasks`` the stage packages (``tasks.grasp``, ``tasks.simulate``, ...) and top-level modules form no
circle, nor do the modules inside one package; imports of our own modules sit at module level (a
function-level import is how a circle hides). Imports under ``if TYPE_CHECKING:`` count like the others.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("schemas", "tasks", "flows")
"""Our top-level packages, lowest layer first."""

LAZY_THIRD_PARTY: dict[str, str] = {
    "jsonschema": "validating a descriptor file only; its import costs ~0.3 s of every command's start-up",
    "open3d": "reading a mesh or point-cloud file only; ~1 s and 900 MB of libraries that pbd ingest never needs",
    "prefect_dask": "pbd archive --address only; dask.distributed costs ~1 s of every flow command's start-up",
    "rosbags": "decoding message types the bulk numpy path does not cover; ~20 ms of a 0.4 s marker ingest",
    "yaml": "reading a topic map or a rosbag2 metadata.yaml only; ~13 ms of every pbd ingest's start-up",
}
"""Third-party modules a function may import late, with the start-up cost that justifies it."""


@dataclass(frozen=True)
class Edge:
    """``source`` imports ``target`` (both dotted module names of ours) at ``line``; ``lazy``: inside a function."""

    source: str
    target: str
    line: int
    lazy: bool


def module_name(path: Path) -> str:
    """Dotted module name of a source file under the repository root."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def sources() -> dict[str, Path]:
    """Every module of our packages by dotted name."""
    return {module_name(p): p for layer in LAYERS for p in sorted((ROOT / layer).rglob("*.py"))}


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module of ours ``name`` refers to (a module, or the package holding the imported name)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _imports(tree: ast.AST, module: str) -> Iterator[tuple[str, int, bool]]:
    """(imported dotted name, line, inside a function) for every import statement of a module."""

    def walk(node: ast.AST, lazy: bool) -> Iterator[tuple[str, int, bool]]:
        for child in ast.iter_child_nodes(node):
            inner = lazy or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            if isinstance(child, ast.Import):
                for alias in child.names:
                    yield alias.name, child.lineno, lazy
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    package = module.split(".")[: -child.level] if child.level else []
                    base = ".".join([*package, base]) if base else ".".join(package)
                for alias in child.names:
                    yield f"{base}.{alias.name}", child.lineno, lazy
            yield from walk(child, inner)

    yield from walk(tree, False)


def graph() -> tuple[list[Edge], list[tuple[str, str, int]]]:
    """Edges between our modules, and (module, third-party name, line) of function-level third-party imports."""
    modules = sources()
    edges: list[Edge] = []
    lazy_third: list[tuple[str, str, int]] = []
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        for imported, line, lazy in _imports(tree, name):
            top = imported.split(".")[0]
            if top in LAYERS:
                target = _resolve(imported, modules)
                if target is not None and target != name:
                    edges.append(Edge(name, target, line, lazy))
            elif lazy:
                lazy_third.append((name, top, line))
    return edges, lazy_third


def unit(module: str) -> str:
    """The node a module counts as in the package graph: ``tasks.<stage>`` for a stage package's modules,
    else the module itself (``tasks.errors``, ``flows.cli``, ``schemas.descriptor``)."""
    parts = module.split(".")
    if len(parts) >= 3 and (ROOT / parts[0] / parts[1]).is_dir():
        return ".".join(parts[:2])
    return module


def find_cycle(nodes: set[str], succ: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the directed graph as a list of nodes (first repeated at the end), None when acyclic."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(succ.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)) is not None:
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(nodes):
        if node not in state and (found := visit(node)) is not None:
            return found
    return None


EDGES, LAZY_THIRD = graph()


def test_graph_is_read() -> None:
    """The walk finds the modules and their imports (a broken walk would pass every other test)."""
    assert any(e.source == "flows.cli" and e.target.startswith("flows.") for e in EDGES)
    assert any(e.source.startswith("tasks.grasp.") and e.target == "tasks.errors" for e in EDGES)


@pytest.mark.parametrize("layer", LAYERS)
def test_imports_point_down(layer: str) -> None:
    """A module of a layer imports nothing from a higher layer."""
    rank = LAYERS.index(layer)
    upward = [
        f"{e.source}:{e.line} imports {e.target}"
        for e in EDGES
        if e.source.split(".")[0] == layer and LAYERS.index(e.target.split(".")[0]) > rank
    ]
    assert upward == []


def test_no_function_level_imports_of_ours() -> None:
    """Our modules are imported at module level only (the CLI dispatches to commands by importlib name)."""
    assert [f"{e.source}:{e.line} imports {e.target}" for e in EDGES if e.lazy] == []


def test_function_level_third_party_imports_are_listed() -> None:
    """A late import of a third-party module is one of the few whose start-up cost is stated above."""
    assert sorted({f"{m}:{line} imports {name}" for m, name, line in LAZY_THIRD if name not in LAZY_THIRD_PARTY}) == []


def test_no_circle_between_packages() -> None:
    """Stage packages and top-level modules import each other in one direction only."""
    succ: dict[str, set[str]] = {}
    nodes: set[str] = set()
    for e in EDGES:
        a, b = unit(e.source), unit(e.target)
        nodes |= {a, b}
        if a != b:
            succ.setdefault(a, set()).add(b)
    assert find_cycle(nodes, succ) is None


def test_no_circle_between_modules() -> None:
    """Inside a package too, modules import each other in one direction only."""
    succ: dict[str, set[str]] = {}
    for e in EDGES:
        succ.setdefault(e.source, set()).add(e.target)
    assert find_cycle(set(sources()), succ) is None


def test_find_cycle_finds_one() -> None:
    """The cycle search reports a circle of three and passes a chain."""
    assert find_cycle({"a", "b", "c"}, {"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a", "b", "c"}, {"a": {"b"}, "b": {"c"}}) is None
