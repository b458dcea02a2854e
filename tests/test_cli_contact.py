"""``tactilab contact``: help, runs on small grids (sphere, profile, height map, scene), --json, --force;
every refused input one line on stderr with exit status 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactilab.cli.contact_inputs import check_memory, memory_estimate
from tactilab.cli.main import main

SPHERE = ["contact", "sphere:R=10mm", "--normal-force", "0.5N", "--grid", "32", "--quiet"]


def _fails(argv, capsys, match):
    """The command exits 2 with one line on stderr that contains ``match`` (a regular expression)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1, err
    import re

    assert re.search(match, err), err


def test_help_states_units_and_the_grid_rule(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["contact", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    for phrase in ("sphere:R=10mm", "sinusoid:A=5um,p=1mm", "rough:rms=2um,hurst=0.8,seed=1", "0.8N",
                   "3 Hertz contact diameters", "--grid-spacing", "kPa"):
        assert phrase in text, phrase


@pytest.mark.parametrize(("extra", "match"), [
    (["--normal-force", "0.5"], "--normal-force: '0.5' has no unit"),
    (["--normal-force=-0.5N"], "--normal-force: must be > 0"),
    (["--normal-force", "0.5N", "--approach", "5um"], "give exactly one, got --normal-force, --approach"),
    (["--mean-pressure", "10kPa"], "--mean-pressure: a mean pressure needs a periodic cell"),
    (["--approach", "5"], "--approach: '5' has no unit"),
    (["--normal-force", "0.5N", "--friction", "-0.1"], "--friction: the Coulomb coefficient must be >= 0"),
    (["--normal-force", "0.5N", "--friction", "x"], "argument --friction: invalid float value"),
    (["--normal-force", "0.5N", "--condition", "glued"], "argument --condition: invalid choice"),
    (["--normal-force", "0.5N", "--tangential-force", "0.2"], "--tangential-force: '0.2' has no unit"),
    (["--normal-force", "0.5N", "--tangential-force", "1N,2N,3N"], "--tangential-force: expected 1 or 2"),
    (["--normal-force", "0.5N", "--slide-direction", "0,0"], "--slide-direction: must not be zero"),
    (["--normal-force", "0.5N", "--slide-direction", "1mm,0"], "--slide-direction: unit 'mm' measures length"),
    (["--normal-force", "0.5N", "--young-modulus", "1"], "--young-modulus: '1' has no unit"),
    (["--normal-force", "0.5N", "--young-modulus=-1MPa"], "--young-modulus: must be > 0"),
    (["--normal-force", "0.5N", "--nu", "0.7"], r"--nu: Poisson's ratio must be in \(-1, 0.5\]"),
    (["--normal-force", "0.5N", "--tol", "0"], r"--tol: must be in \(0, 1\)"),
    (["--normal-force", "0.5N", "--depth", "1"], "--depth: '1' has no unit"),
    (["--normal-force", "0.5N", "--depth=-1mm"], "--depth: must be > 0"),
    (["--normal-force", "0.5N", "--grid", "4"], "--grid: expected N or NX,NY with at least 8 nodes"),
    (["--normal-force", "0.5N", "--grid", "a"], "--grid: expected N or NX,NY"),
    (["--normal-force", "0.5N", "--grid-spacing=-5um"], "--grid-spacing: must be > 0"),
    (["--normal-force", "0.5N", "--finger-radius", "10mm"], "SURFACE sphere: give its radius once"),
    (["--normal-force", "0.5N", "--spacing", "10um"], "--spacing, --height-unit: they describe a .npy"),
    (["--normal-force", "0.5N", "--grid", "1000000"], r"--grid: .* needs about .* GiB, above the limit .* use at "
                                                       r"most \d+ nodes per axis"),
])
def test_refused_options_name_the_option(extra, match, capsys, tmp_path):
    argv = ["contact", "sphere:R=10mm", "--out", str(tmp_path / "o"), *extra]
    _fails(argv, capsys, match)
    assert not (tmp_path / "o").exists()  # refused before any folder is made


@pytest.mark.parametrize(("surface", "extra", "match"), [
    ("nowhere.npy", [], "SURFACE: 'nowhere.npy' is neither a file nor a built-in"),
    ("sphere:R=10mm,B=2", [], "'B=2' is not a parameter of sphere"),
    ("sphere:", [], "SURFACE sphere: give its radius once"),
    ("sinusoid:A=5um", ["--periodic"], "SURFACE sinusoid: p missing"),
    ("sinusoid:A=5um,p=1mm", [], "--periodic: a surface without a finger is a nominally flat contact"),
    ("sinusoid:A=5um,p=0.3mm", ["--periodic", "--grid-spacing", "10um", "--grid", "32"],
     "a periodic grid must hold whole periods"),
    ("rough:hurst=0.8", ["--periodic"], "SURFACE rough: give exactly one of rms="),
    ("rough:rms=2um,seed=x", ["--periodic"], "SURFACE rough: seed must be an integer"),
    ("rough:rms=2", ["--periodic"], "rough rms: '2' has no unit"),
])
def test_refused_surfaces(surface, extra, match, capsys, tmp_path):
    _fails(["contact", surface, "--normal-force", "0.5N", "--out", str(tmp_path / "o"), *extra], capsys, match)


def test_refused_height_map_options(capsys, tmp_path):
    np.save(tmp_path / "h.npy", np.zeros((16, 16)))
    base = ["contact", str(tmp_path / "h.npy"), "--normal-force", "0.5N", "--finger-radius", "10mm"]
    _fails(base + ["--height-unit", "um"], capsys, "spacing is missing")
    _fails(base + ["--spacing", "10um"], capsys, "the height unit is missing")
    _fails(base + ["--spacing", "10um", "--height-unit", "um", "--grid", "32"], capsys,
           "--grid, --grid-spacing: a height-map file keeps its own grid")
    (tmp_path / "display.toml").write_text("")
    _fails(["contact", str(tmp_path / "display.toml"), "--normal-force", "0.5N"], capsys, "display.toml")


def test_memory_estimate_pads_isolated_contacts():
    assert memory_estimate((2048, 2048), periodic=False) == 4 * memory_estimate((2048, 2048), periodic=True)
    check_memory((64, 64), periodic=False, limit=10**9)
    with pytest.raises(ValueError, match=r"use at most 1024 nodes per axis"):
        check_memory((2048, 2048), periodic=False, limit=memory_estimate((1024, 1024), periodic=False))
    with pytest.raises(ValueError, match=r"use at most 2048 nodes per axis"):
        check_memory((4096, 4096), periodic=True, limit=memory_estimate((2048, 2048), periodic=True) + 1)
