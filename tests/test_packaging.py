"""Guard the packaging: a wheel silently drops subpackages missing from the list."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARTS = ["core", "data_schemas", "forward", "inversion", "experiments", "demo", "cli"]


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_package_folder_is_listed():
    tool = _pyproject()["tool"]["setuptools"]
    listed = set(tool["packages"])
    package_dir = tool["package-dir"]
    found = {"tactilab"} if (ROOT / "toplevel" / "__init__.py").is_file() else set()
    for part in PARTS:
        for init in (ROOT / part).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / part).parts
            found.add(".".join(("tactilab", part, *rel)))
    missing = found - listed
    assert not missing, f"add {sorted(missing)} to [tool.setuptools].packages in pyproject.toml"
    stale = listed - found
    assert not stale, f"{sorted(stale)} listed in pyproject.toml but have no __init__.py"
    for part in PARTS:
        assert package_dir[f"tactilab.{part}"] == part
    assert "tactilab" in listed and package_dir["tactilab"] == "toplevel"


def test_the_top_level_package_is_regular_and_lives_apart_from_the_checkout_root():
    """``tactilab/__init__.py`` comes from ``toplevel/``: a regular package, so an installed copy wins
    over a clone named ``tactilab`` in the current directory (a folder without ``__init__.py``)."""
    import tactilab

    assert (ROOT / "toplevel" / "__init__.py").is_file()
    # an editable install loads toplevel/__init__.py itself; a wheel installs it as tactilab/__init__.py
    loaded = Path(tactilab.__file__)
    assert loaded.parent.name in ("toplevel", "tactilab") and loaded.parent != ROOT
    assert loaded.read_bytes() == (ROOT / "toplevel" / "__init__.py").read_bytes()
    assert not (ROOT / "tactilab" / "__init__.py").exists()
    assert not (ROOT / "__init__.py").exists()
    assert not [p for p in (ROOT / "toplevel").iterdir() if p.name not in ("__init__.py", "__pycache__")]


def test_installed_parts_come_from_the_mapped_folders():
    import importlib

    for part in PARTS:
        module = importlib.import_module(f"tactilab.{part}")
        assert Path(module.__file__).parent.name == part


def test_console_script_and_test_extra():
    project = _pyproject()["project"]
    assert project["scripts"]["tactilab"] == "tactilab.cli.main:main"
    assert project["requires-python"] == ">=3.12"
    deps = " ".join(project["dependencies"])
    for name in ["numpy", "scipy", "pandas", "emcee", "arviz>=1", "xarray", "pydantic>=2", "matplotlib"]:
        assert name in deps, name
    assert any(d.startswith("pytest") for d in project["optional-dependencies"]["test"])
    assert any(d.startswith("hypothesis") for d in project["optional-dependencies"]["test"])
