"""The package layout is the design: which subpackage may import which, read from the code with ``ast``.

``osim`` reads OpenSim (the only place that imports ``opensim``), ``mj`` is the MuJoCo side,
``convert`` writes MJCF, ``validate`` compares, ``paper`` is the experiment, ``viz`` shows.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "o2m"

#: Subpackage -> the o2m subpackages it may import (shared top-level modules are always allowed).
ALLOWED = {
    "osim": {"mj"},
    "mj": set(),
    "convert": {"osim", "mj"},
    "validate": {"osim", "mj"},
    "paper": {"osim", "mj", "convert", "validate"},
    "viz": {"osim", "mj"},
}
#: Top-level modules every subpackage may use.
SHARED = {"errors", "transforms", "parallel", "models", "activations"}
#: Modules longer than this (lines) need a reason at their top ("Longer than 600 lines: ...").
MAX_LINES = 600


def _modules() -> dict[str, Path]:
    return {".".join(p.relative_to(PACKAGE.parent).with_suffix("").parts): p for p in PACKAGE.rglob("*.py")}


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` except those under ``if TYPE_CHECKING:`` (imports for annotations only)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            continue
        yield node
        yield from _runtime_nodes(node)


def _imports(path: Path) -> set[str]:
    """Every o2m module or package ``path`` imports at run time, at module level or inside functions."""
    out = set()
    for node in _runtime_nodes(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            if node.module.split(".")[0] == "o2m":
                out.add(node.module)
                out.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level:
            out.add("<relative>")
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] in ("o2m", "opensim"))
    return out


def _unit(module: str) -> str:
    """The subpackage (or shared top-level module) a dotted o2m module belongs to."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


GRAPH = {name: _imports(path) for name, path in _modules().items()}


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_imports_follow_the_layout(module):
    """A subpackage imports only the subpackages below it; no relative imports."""
    own = _unit(module)
    assert "<relative>" not in GRAPH[module], f"{module}: use absolute imports"
    if own not in ALLOWED:
        return  # the top level (cli, models, ...) may use everything
    modules = _modules()
    for target in GRAPH[module]:
        if target == "opensim" or target not in modules and target.rsplit(".", 1)[0] not in modules:
            continue
        unit = _unit(target if target in modules else target.rsplit(".", 1)[0])
        assert unit in ALLOWED[own] | SHARED | {own, ""}, f"{module} imports {target}: {own} may not use {unit}"


def test_only_osim_imports_opensim():
    offenders = [m for m, targets in GRAPH.items() if "opensim" in targets and _unit(m) != "osim"]
    assert not offenders, f"import opensim outside o2m.osim: {offenders}"
    assert any("opensim" in t for m, t in GRAPH.items() if m == "o2m.osim.runtime")


def test_no_import_cycles():
    """The module graph (each edge module -> o2m module it imports) has no cycle."""
    modules = _modules()
    edges = {m: {t if t in modules else t.rsplit(".", 1)[0] for t in targets} & set(modules) - {m}
             for m, targets in GRAPH.items()}
    # a package __init__ re-exports its own modules; the edge from a module to its own
    # package (importing a sibling through the package) is what would make a cycle
    state: dict[str, int] = {}

    def visit(m: str, stack: list[str]) -> None:
        if state.get(m) == 2:
            return
        assert state.get(m) != 1, "import cycle: " + " -> ".join(stack[stack.index(m):] + [m])
        state[m] = 1
        for t in sorted(edges[m]):
            visit(t, stack + [m])
        state[m] = 2

    for m in sorted(edges):
        visit(m, [])


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_module_size(module):
    path = _modules()[module]
    lines = path.read_text().splitlines()
    if len(lines) > MAX_LINES:
        head = "\n".join(lines[:40])
        assert f"Longer than {MAX_LINES} lines:" in head, f"{module} has {len(lines)} lines and no reason at its top"


def test_top_level_api():
    import o2m
    from o2m.convert import ConvertOptions, convert

    assert callable(convert) and o2m.ConvertOptions is ConvertOptions
    assert callable(o2m.compare_kinematics) and callable(o2m.compare_muscles)
