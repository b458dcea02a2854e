"""No import cycles in the library, counting the imports inside functions too.

A cycle through a function-level import works until someone moves the import to the top of the
module, or calls the function during the other module's import; then one of the two modules is
half-initialised. The checker reads the source (ast), so it also sees imports that no test runs.
A package's ``__init__`` importing its own submodules is not counted (that is how a face works).
"""

from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("core", "data_schemas", "forward", "inversion", "experiments", "demo", "cli")


def library_modules(root: Path, parts: Iterable[str] = PARTS) -> dict[str, Path]:
    """Dotted name -> file of every module of the library (``tactilab`` itself from ``toplevel/``)."""
    modules = {}
    for part in parts:
        for path in sorted((root / part).rglob("*.py")):
            dotted = ".".join(("tactilab", *path.relative_to(root).with_suffix("").parts))
            modules[dotted.removesuffix(".__init__")] = path
    if (root / "toplevel" / "__init__.py").is_file():
        modules["tactilab"] = root / "toplevel" / "__init__.py"
    return modules


def _targets(module: str, path: Path, node: ast.Import | ast.ImportFrom, modules: dict[str, Path]) -> set[str]:
    """The library modules one import statement loads (the deepest known module of each name)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        if node.level:  # relative: climb from the module's package
            base = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
            base = base[: len(base) - node.level + 1]
            source = ".".join(base + ([node.module] if node.module else []))
        else:
            source = node.module or ""
        # 'from package import submodule' loads the submodule; 'from module import name' the module
        names = [f"{source}.{a.name}" if f"{source}.{a.name}" in modules else source for a in node.names]
    found = set()
    for name in names:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        if name and name != module:
            found.add(name)
    return found


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the library modules it imports anywhere in its source (top level or in functions)."""
    graph = {}
    for module, path in modules.items():
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and getattr(node, "module", None) != "__future__":
                edges |= _targets(module, path, node, modules)
        # a package importing its own submodules (its face) is not a cycle
        graph[module] = {t for t in edges if not t.startswith(module + ".")}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found)


def _path_within(graph: dict[str, set[str]], members: list[str]) -> str:
    """One closed import path through a cycle, for the message: a -> b -> ... -> a."""
    inside = set(members)
    path, node = [members[0]], members[0]
    while True:
        node = min(t for t in graph[node] if t in inside)
        if node in path:
            return " -> ".join(path[path.index(node):] + [node])
        path.append(node)


def test_the_library_has_no_import_cycle():
    graph = import_graph(library_modules(ROOT))
    found = cycles(graph)
    assert not found, "import cycles (counting imports inside functions):\n" + "\n".join(
        _path_within(graph, c) for c in found) + "\nmove the shared code into a module that both import"


def _tree(tmp_path: Path, files: dict[str, str]) -> dict[str, Path]:
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return library_modules(tmp_path, parts=("core", "forward"))


def test_checker_finds_module_level_and_function_level_cycles(tmp_path):
    modules = _tree(tmp_path, {
        "core/__init__.py": "",
        "core/a.py": "from .b import thing\n",
        "core/b.py": "def f():\n    from tactilab.core import a\n",
        "forward/__init__.py": "from . import x\n",
        "forward/x.py": "import tactilab.forward.y\n",
        "forward/y.py": "from tactilab.forward import x\n",
    })
    graph = import_graph(modules)
    assert graph["tactilab.core.b"] == {"tactilab.core.a"}  # 'from package import module' is the module
    assert cycles(graph) == [["tactilab.core.a", "tactilab.core.b"], ["tactilab.forward.x", "tactilab.forward.y"]]
    assert _path_within(graph, ["tactilab.core.a", "tactilab.core.b"]) == (
        "tactilab.core.a -> tactilab.core.b -> tactilab.core.a")


def test_checker_ignores_a_face_importing_its_own_modules_and_one_way_imports(tmp_path):
    modules = _tree(tmp_path, {
        "core/__init__.py": "from .rules import positive\nfrom . import rules\n",
        "core/rules.py": "import math\nfrom tactilab.core import faces\n",
        "core/faces.py": "",
        "forward/__init__.py": "",
        "forward/x.py": "from ..core.rules import positive\nfrom tactilab.core import rules\n",
    })
    graph = import_graph(modules)
    assert graph["tactilab.forward.x"] == {"tactilab.core.rules"}
    assert graph["tactilab.core"] == set()
    assert cycles(graph) == []
