"""A folder named ``tactilab`` in the current directory shadows the installed namespace package: warned."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_a_checkout_in_the_current_directory_is_reported(tmp_path):
    shadow = tmp_path / "tactilab"
    shutil.copytree(ROOT / "data_schemas", shadow / "data_schemas", ignore=shutil.ignore_patterns("__pycache__"))
    code = "import tactilab.data_schemas as d; print(d.__file__)"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(shadow / "data_schemas" / "__init__.py")  # the pitfall is real
    assert "ShadowedInstallWarning: tactilab.data_schemas was imported from" in out.stderr
    assert "shadows the installed package" in out.stderr
    clean = subprocess.run([sys.executable, "-W", "error::UserWarning", "-c", code], cwd=ROOT.parent,
                           capture_output=True, text=True)
    assert clean.returncode == 0 and "Shadowed" not in clean.stderr


def test_check_origin_accepts_the_installed_face_and_warns_otherwise(tmp_path):
    import tactilab.forward as face
    from tactilab.data_schemas._lazy import ShadowedInstallWarning, check_origin

    assert check_origin("tactilab.forward", face.__file__)
    with pytest.warns(ShadowedInstallWarning, match=r"tactilab.forward was imported from .*shadows the installed"):
        assert not check_origin("tactilab.forward", str(tmp_path / "tactilab" / "forward" / "__init__.py"))


def test_nested_packages_are_checked_against_their_own_folder():
    import tactilab.forward.halfspace as door
    from tactilab.data_schemas._lazy import check_origin

    assert check_origin("tactilab.forward.halfspace", door.__file__)
