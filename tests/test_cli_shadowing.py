"""A folder named ``tactilab`` in the current directory (a clone) and the installed package.

``tactilab`` is a regular package (``toplevel/__init__.py``), so an installed copy on ``sys.path``
wins over a folder without ``__init__.py`` in the current directory. An editable install is found
by setuptools' finder after Python's path finder, so there a different checkout in the current
directory still loads first: :func:`tactilab.core.check_origin` warns about it.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
IMPORT = "import tactilab, tactilab.core as c; print(tactilab.__version__); print(c.__file__)"


def _run(code: str, cwd: Path, **env) -> subprocess.CompletedProcess:
    import os

    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, **env})


def _shadow(tmp_path: Path) -> Path:
    """A folder ``tactilab`` (no ``__init__.py``, like a clone) holding a copy of ``core``."""
    shadow = tmp_path / "cwd" / "tactilab"
    shutil.copytree(ROOT / "core", shadow / "core", ignore=shutil.ignore_patterns("__pycache__"))
    return shadow


def test_an_installed_regular_package_wins_over_a_clone_in_the_current_directory(tmp_path):
    shadow = _shadow(tmp_path)
    site = tmp_path / "site" / "tactilab"  # what a wheel puts in site-packages
    shutil.copytree(ROOT / "core", site / "core", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "toplevel" / "__init__.py", site / "__init__.py")
    out = _run(IMPORT + "; print(tactilab.__file__)", shadow.parent, PYTHONPATH=str(site.parent),
               PYTHONWARNINGS="ignore::UserWarning")
    assert out.returncode == 0, out.stderr
    version, core_file, top_file = out.stdout.split()
    assert version
    assert Path(top_file) == site / "__init__.py"
    assert Path(core_file) == site / "core" / "__init__.py"  # not the clone's copy


def test_a_different_checkout_in_the_current_directory_is_reported_or_ignored(tmp_path):
    from tactilab.core.faces import _installed

    shadow = _shadow(tmp_path)
    out = _run("import tactilab.core as c; print(c.__file__)", shadow.parent)
    assert out.returncode == 0, out.stderr
    core_file = Path(out.stdout.split()[-1])
    if _installed()[1] is not None:  # editable: the path finder takes the clone first, and says so
        assert core_file == shadow / "core" / "__init__.py"
        assert "ShadowedInstallWarning: tactilab.core was imported from" in out.stderr
        assert "shadows the installed package" in out.stderr
    else:  # a wheel: the installed regular package wins
        assert core_file != shadow / "core" / "__init__.py"
        assert "Shadowed" not in out.stderr


@pytest.mark.parametrize("where", ["checkout", "elsewhere"])
def test_no_warning_from_the_checkout_or_an_empty_folder(tmp_path, where):
    cwd = ROOT if where == "checkout" else tmp_path
    out = subprocess.run([sys.executable, "-W", "error::UserWarning", "-c", IMPORT], cwd=cwd,
                         capture_output=True, text=True)
    assert out.returncode == 0 and "Shadowed" not in out.stderr, out.stderr
    assert out.stdout.split()[0] not in ("", "None")


def test_check_origin_accepts_the_installed_face_and_warns_otherwise(tmp_path):
    import tactilab.forward as face
    from tactilab.core import ShadowedInstallWarning, check_origin

    assert check_origin("tactilab.forward", face.__file__)
    with pytest.warns(ShadowedInstallWarning, match=r"tactilab.forward was imported from .*shadows the installed"):
        assert not check_origin("tactilab.forward", str(tmp_path / "tactilab" / "forward" / "__init__.py"))


def test_nested_packages_are_checked_against_their_own_folder():
    import tactilab.forward.halfspace as door
    from tactilab.core import check_origin

    assert check_origin("tactilab.forward.halfspace", door.__file__)


def test_the_top_level_package_has_the_version():
    import tactilab
    from tactilab.core import package_version

    assert tactilab.__version__ == package_version() != "0+unknown"
    # an editable install loads toplevel/__init__.py itself; a wheel installs it as tactilab/__init__.py
    loaded = Path(tactilab.__file__)
    assert loaded.parent.name in ("toplevel", "tactilab")
    assert loaded.read_bytes() == (ROOT / "toplevel" / "__init__.py").read_bytes()
