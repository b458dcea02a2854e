"""The inversion part's modules import each other at module level only, and without cycles
(a cycle held apart by an import inside a function breaks when someone moves that import)."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "inversion"


def sibling_imports(path: Path) -> tuple[set[str], list[str]]:
    """(siblings imported at module level, siblings imported inside a function or class)."""
    tree = ast.parse(path.read_text())
    top, nested = set(), []
    top_nodes = set(map(id, tree.body))
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level == 1 and node.module:
            name = node.module.split(".")[0]
        elif node.level == 0 and (node.module or "").startswith("tactilab.inversion."):
            name = node.module.split(".")[2]
        else:
            continue
        (top.add(name) if id(node) in top_nodes else nested.append(f"{name} (line {node.lineno})"))
    return top, nested


def graph() -> dict[str, set[str]]:
    return {p.stem: sibling_imports(p)[0] for p in ROOT.glob("*.py") if p.stem != "__init__"}


def test_no_sibling_import_inside_a_function():
    for path in ROOT.glob("*.py"):
        _, nested = sibling_imports(path)
        assert not nested, f"{path.name}: imports inside functions: {nested}; import at module level"


def test_module_graph_has_no_cycle():
    g = graph()
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in g.get(node, ()):
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*stack, node, nxt]))
            if nxt not in state:
                visit(nxt, [*stack, node])
        state[node] = 2

    for mod in g:
        if mod not in state:
            visit(mod, [])
    assert {"linear", "tv", "linear_common"} <= set(g)
    assert "linear_common" in g["tv"] and "linear" not in g["tv"]


def test_each_module_imports_first_in_a_fresh_interpreter():
    """tv and linear, each imported first in a fresh interpreter, load: no import order is required."""
    names = ["tv", "linear"]
    code = "import importlib, sys\nfor n in sys.argv[1:]:\n    importlib.import_module('tactilab.inversion.' + n)\n"
    for name in names:
        out = subprocess.run([sys.executable, "-c", code, name], capture_output=True, text=True)
        assert out.returncode == 0, f"{name}: {out.stderr[-500:]}"
    assert importlib.import_module("tactilab.inversion.tv").invert_tv is importlib.import_module(
        "tactilab.inversion.linear").invert_tv
