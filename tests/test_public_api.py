"""The public faces: every exported name imports and is documented; the docs' code runs.

Each part (``tactilab.data_schemas``, ``tactilab.forward``, ``tactilab.inversion``,
``tactilab.experiments``) has one face, its ``__init__.py``, that lists its public names in
``__all__`` and resolves them lazily. These tests check the faces, that ``tactilab --help`` does
not load heavy modules it does not need, and that every ```python block in the docs imports only
from faces and runs as written.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FACES = ("core", "data_schemas", "forward", "inversion", "experiments")
DOCS = sorted([*ROOT.glob("docs/*.md"), ROOT / "README.md"])
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


def _face_names() -> list[tuple[str, str]]:
    out = []
    for part in FACES:
        face = importlib.import_module(f"tactilab.{part}")
        out += [(part, name) for name in face.__all__]
    return out


def _assignment_comment(part: str, name: str) -> str | None:
    """The ``#:`` comment just above the top-level assignment of ``name`` in the part's source
    (or in ``core/``, the ground floor whose constants every part may re-export)."""
    assign = re.compile(rf"^(?:\w+\s*,\s*)*{re.escape(name)}(?:\s*,\s*\w+)*\s*(?::[^=]*)?=")
    for path in [*sorted((ROOT / part).rglob("*.py")), *sorted((ROOT / "core").rglob("*.py"))]:
        lines = path.read_text().splitlines()
        for i, line in enumerate(lines):
            if assign.match(line):
                above = lines[i - 1].strip() if i else ""
                return above[2:].strip() if above.startswith("#:") else ""
    return None


@pytest.mark.parametrize("part", FACES)
def test_face_declares_all_and_version(part):
    face = importlib.import_module(f"tactilab.{part}")
    assert face.__doc__ and face.__doc__.strip(), f"tactilab.{part} has no module docstring"
    assert isinstance(face.__version__, str) and face.__version__
    assert list(face.__all__) == sorted(set(face.__all__)), f"tactilab.{part}.__all__ is not sorted and unique"
    assert set(face.__all__) <= set(dir(face))
    with pytest.raises(AttributeError, match=f"module 'tactilab.{part}' has no attribute 'no_such_name'"):
        face.no_such_name  # noqa: B018


@pytest.mark.parametrize(("part", "name"), _face_names())
def test_every_public_name_imports_and_has_a_docstring(part, name):
    face = importlib.import_module(f"tactilab.{part}")
    value = getattr(face, name)
    exec(f"from tactilab.{part} import {name}", {})  # the documented spelling works too
    if inspect.isclass(value) or inspect.isroutine(value):
        # the object's own docstring: not inherited, not the signature a dataclass makes up
        doc = (value.__dict__.get("__doc__") if inspect.isclass(value) else value.__doc__) or ""
        assert doc.strip() and not doc.startswith(f"{value.__name__}("), f"tactilab.{part}.{name} has no docstring"
        assert value.__module__.startswith((f"tactilab.{part}", "tactilab.core")), (
            f"tactilab.{part}.{name} is defined in {value.__module__}, outside its part and the ground floor")
    else:  # a constant: documented by a '#:' comment above its assignment
        comment = _assignment_comment(part, name)
        assert comment is not None, f"tactilab.{part}.{name}: no top-level assignment found in {part}/"
        assert comment, f"tactilab.{part}.{name}: put a '#: what it is' comment above its assignment"


def test_cli_help_does_not_import_heavy_modules():
    """``tactilab --help`` parses and prints: it must not pay for sampling, plotting or the solver."""
    code = (
        "import sys, contextlib, io\n"
        "import tactilab.cli.main as m\n"
        "buf = io.StringIO()\n"
        "with contextlib.redirect_stdout(buf):\n"
        "    try:\n"
        "        m.main(['--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "assert 'usage' in buf.getvalue().lower(), buf.getvalue()\n"
        "heavy = ['emcee', 'arviz', 'matplotlib', 'scipy', 'xarray', 'pandas', 'pydantic', 'h5py',\n"
        "         'tactilab.forward.halfspace', 'tactilab.inversion.mcmc', 'tactilab.demo']\n"
        "print(' '.join(h for h in heavy if h in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"tactilab --help imported: {out.stdout.strip()}"


# ----------------------------------------------------------------------------- the docs' code
def _blocks(path: Path) -> list[str]:
    return FENCE.findall(path.read_text())


DOCS_WITH_CODE = [p for p in DOCS if _blocks(p)]


def _deep_imports(code: str) -> list[str]:
    """Imports of tactilab modules other than the part faces."""
    bad = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            bad += [a.name for a in node.names if a.name.startswith("tactilab")]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("tactilab"):
            if node.module not in {f"tactilab.{part}" for part in FACES}:
                bad.append(node.module)
    return bad


def test_some_docs_have_code():
    assert len(DOCS_WITH_CODE) >= 3, [p.name for p in DOCS_WITH_CODE]


def test_deep_import_check_catches_deep_modules():
    assert _deep_imports("from tactilab.forward.halfspace.facade import HalfSpace") == [
        "tactilab.forward.halfspace.facade"]
    assert _deep_imports("import tactilab.forward") == ["tactilab.forward"]
    assert _deep_imports("from tactilab.forward import HalfSpace\nimport numpy as np") == []


@pytest.mark.parametrize("path", DOCS_WITH_CODE, ids=lambda p: p.name)
def test_docs_code_imports_only_from_faces(path):
    for i, code in enumerate(_blocks(path)):
        assert not _deep_imports(code), f"{path.name} block {i + 1} imports deep modules: {_deep_imports(code)}"


@pytest.mark.slow
@pytest.mark.parametrize("path", DOCS_WITH_CODE, ids=lambda p: p.name)
def test_docs_code_runs(path, tmp_path, monkeypatch):
    """A docs file's python blocks, in order, in one fresh namespace, in an empty working folder
    that holds a copy of the repository's ``examples/`` (the docs' commands run from the root)."""
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": f"docs_{path.stem}"}
    for i, code in enumerate(_blocks(path)):
        exec(compile(code, f"{path.relative_to(ROOT)} block {i + 1}", "exec"), namespace)  # noqa: S102
    assert os.getcwd() == str(tmp_path)


# ----------------------------------------------------------------------------- plotting etiquette
LIBRARY = ("data_schemas", "forward", "inversion", "experiments", "demo", "cli")


def test_library_code_never_switches_the_matplotlib_backend():
    """Figures are built as matplotlib.figure.Figure; no matplotlib.use(...) and no pyplot."""
    found = []
    for part in LIBRARY:
        for path in sorted((ROOT / part).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "use" \
                        and isinstance(node.func.value, ast.Name) and node.func.value.id == "matplotlib":
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} matplotlib.use")
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [f"{node.module}.{a.name}" for a in node.names] if isinstance(node, ast.ImportFrom)
                         else [])
                found += [f"{path.relative_to(ROOT)}:{node.lineno} {n}" for n in names if "pyplot" in n]
    assert not found, found


def test_plotting_keeps_the_callers_backend(tmp_path):
    code = (
        "import matplotlib\n"
        "matplotlib.use('svg')\n"
        "import numpy as np, xarray as xr\n"
        "from tactilab.forward import plot_field\n"
        "da = xr.DataArray(np.ones((1, 1, 4)), dims=('depth', 'component', 'x'),\n"
        "                  coords={'depth': [1e-3], 'component': ['zz'], 'x': np.arange(4) * 1e-4},\n"
        "                  attrs={'quantity': 'stress'})\n"
        f"plot_field(da, {str(tmp_path / 'f.png')!r})\n"
        "print(matplotlib.get_backend())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "svg" and (tmp_path / "f.png").stat().st_size > 0
