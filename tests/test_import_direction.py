"""Imports flow one way: core <- data_schemas <- forward <- inversion <- experiments <- demo <- cli."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYER = {"core": 0, "data_schemas": 1, "forward": 2, "inversion": 3, "experiments": 4, "demo": 5, "cli": 6}


def imported_parts(source: str, part: str, module_parts: tuple[str, ...]) -> set[str]:
    """Return the tactilab parts that ``source`` (a module of ``part``) imports."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: stays within the part unless it climbs out
                if node.level - 1 > len(module_parts):
                    found.add("<relative import leaving its part>")
                continue
            names = [node.module or ""]
        else:
            continue
        for name in names:
            bits = name.split(".")
            if bits[0] == "tactilab" and len(bits) > 1:
                found.add(bits[1])
            elif bits[0] in LAYER:  # a bare 'import forward' works only from the source tree
                found.add(f"<bare {bits[0]}>")
    return found


def _modules():
    for part in LAYER:
        for path in sorted((ROOT / part).rglob("*.py")):
            yield part, path


@pytest.mark.parametrize("part,path", list(_modules()), ids=lambda v: str(v))
def test_imports_flow_one_way(part, path):
    rel = path.relative_to(ROOT / part).parts[:-1]
    for target in imported_parts(path.read_text(), part, rel):
        assert target in LAYER, f"{path}: import {target} is not an absolute tactilab import"
        if part == "cli":
            continue
        assert target != "cli", f"{path}: nothing may import tactilab.cli"
        assert LAYER[target] <= LAYER[part], (
            f"{path}: tactilab.{part} may not import tactilab.{target} "
            "(core <- data_schemas <- forward <- inversion <- experiments <- demo <- cli)"
        )


@pytest.mark.parametrize("path", sorted((ROOT / "core").rglob("*.py")), ids=lambda p: p.name)
def test_core_imports_no_other_part(path):
    """The ground floor stands alone: it names no touch concept and imports no other part."""
    parts = imported_parts(path.read_text(), "core", path.relative_to(ROOT / "core").parts[:-1])
    assert parts <= {"core"}, f"{path}: tactilab.core may import only itself, not {sorted(parts - {'core'})}"


def test_the_top_level_package_imports_only_core():
    parts = imported_parts((ROOT / "toplevel" / "__init__.py").read_text(), "toplevel", ())
    assert parts == {"core"}, "tactilab/__init__.py (toplevel/) must stay light: it may import only tactilab.core"


def test_checker_catches_a_backward_import():
    src = "from tactilab.experiments import runner\nimport tactilab.cli.main\n"
    assert imported_parts(src, "forward", ()) == {"experiments", "cli"}
    assert imported_parts("from ..x import y", "forward", ()) == {"<relative import leaving its part>"}
    assert imported_parts("from .x import y", "forward", ()) == set()


#: the rooms of tactilab.forward that have their own door
ROOMS = ("halfspace", "contact", "skin")


def door_breaches(source: str, in_forward: bool, room: str = "halfspace") -> set[str]:
    """Imports of a room's inner modules (``forward/<room>/*``) from outside the room."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1 and in_forward and (node.module or "").startswith(f"{room}."):
                found.add(f".{node.module}")
            elif node.level == 0 and (node.module or "").startswith(f"tactilab.forward.{room}."):
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith(f"tactilab.forward.{room}.")}
    return found


def _library_modules_outside_a_room():
    for room in ROOMS:
        for part in LAYER:
            for path in sorted((ROOT / part).rglob("*.py")):
                if (ROOT / "forward" / room) not in path.parents:
                    yield room, part, path


@pytest.mark.parametrize("room,part,path", list(_library_modules_outside_a_room()), ids=lambda v: str(v))
def test_each_room_has_one_door(room, part, path):
    breaches = door_breaches(path.read_text(), part == "forward", room)
    assert not breaches, (
        f"{path}: import from tactilab.forward.{room} (its door), not {sorted(breaches)}"
    )


def test_door_checker_catches_a_breach():
    assert door_breaches("from .halfspace.kernels import point_green", True) == {".halfspace.kernels"}
    assert door_breaches("from tactilab.forward.halfspace.spectral import transfer", False) == {
        "tactilab.forward.halfspace.spectral"}
    assert door_breaches("from .halfspace import HalfSpace", True) == set()
    assert door_breaches("from .contact.hertz import HertzContact", True, "contact") == {".contact.hertz"}


FACES = {"tactilab.core", "tactilab.data_schemas", "tactilab.forward", "tactilab.inversion", "tactilab.experiments",
         "tactilab.demo"}


def deep_imports(source: str) -> set[str]:
    """Imports of tactilab modules other than the part faces (``from tactilab.forward import X`` is fine)."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("tactilab."):
            if node.module not in FACES:
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("tactilab.") and a.name not in FACES}
    return found


@pytest.mark.parametrize("path", sorted((ROOT / "demo").glob("*.py")), ids=lambda p: p.name)
def test_the_demo_imports_only_from_faces(path):
    """The demo is what users copy: it imports what they can import, from the faces."""
    deep = deep_imports(path.read_text())
    assert not deep, f"{path}: import from the faces, not {sorted(deep)} (add a missing name to its face's _EXPORTS)"


def test_deep_import_checker():
    assert deep_imports("from tactilab.forward.tractors import pair_phi_psi") == {"tactilab.forward.tractors"}
    assert deep_imports("import tactilab.inversion.mcmc") == {"tactilab.inversion.mcmc"}
    assert deep_imports("from tactilab.forward import HalfSpace\nfrom .sections import x") == set()
