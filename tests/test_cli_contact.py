"""``tactilab contact``: help, runs on small grids (sphere, profile, height map, scene), --json, --force;
every refused input one line on stderr with exit status 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactilab.cli.contact_inputs import check_memory
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
    (["--normal-force", "0.5N", "--young-modulus=-1MPa"], "--young-modulus: Young's modulus must be finite and > 0 Pa"),
    (["--normal-force", "0.5N", "--nu", "0.7"], r"--nu: Poisson's ratio must lie in \(-1, 0.5\]"),
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


def test_memory_check_names_the_grid_that_fits():
    from tactilab.forward.contact import memory_estimate

    assert memory_estimate((2048, 2048), False, "frictionless") > memory_estimate((2048, 2048), True, "frictionless")
    need = memory_estimate((64, 64), False, "frictionless")
    assert check_memory((64, 64), False, "frictionless", limit=10**9) == need
    with pytest.raises(ValueError, match=r"isolated .* on 2048 x 2048 nodes .* use at most 1024 nodes per axis"):
        check_memory((2048, 2048), False, "partial", limit=memory_estimate((1024, 1024), False, "partial"))
    with pytest.raises(ValueError, match=r"use at most 2048 nodes per axis"):
        check_memory((4096, 4096), True, "frictionless", limit=memory_estimate((2048, 2048), True, "frictionless") + 1)


# --------------------------------------------------------------------------------------------- runs
@pytest.mark.slow
def test_sphere_run_prints_the_summary_and_writes_the_files(tmp_path, capsys):
    """A Hertz sphere on 32^2 nodes: the summary's numbers, the solution file and the three PNGs."""
    import xarray as xr

    out = tmp_path / "out"
    assert main([*SPHERE, "--depth", "1mm,2mm", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for phrase in ("contact area", "fraction", "peak pressure", "iterations", "error estimate:", "warnings: 0",
                   "dropped: stick/slip map: frictionless contact"):
        assert phrase in text, phrase
    assert sorted(p.name for p in out.iterdir()) == ["contact.nc", "pressure.png", "strain.nc", "strain.png"]
    with xr.open_dataset(out / "contact.nc", engine="h5netcdf") as ds:
        p = ds["pressure"].values
        cell = float(np.diff(ds["x"].values[:2])[0]) ** 2
    assert p.sum() * cell == pytest.approx(0.5, rel=1e-9)  # the total force is exact
    a = (3 * 0.5 * 10e-3 / (4 * 1e6 / 0.75)) ** (1 / 3)  # Hertz contact radius
    area = float(text.split("contact area ")[1].split(" mm^2")[0]) * 1e-6
    assert np.sqrt(area / np.pi) == pytest.approx(a, abs=2 * np.sqrt(cell))


def test_json_prints_one_object_and_force_overwrites(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*SPHERE, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["command"] == "contact" and summary["normal_force_n"] == pytest.approx(0.5, rel=1e-9)
    assert summary["converged"] is True and summary["iterations"] > 0 and summary["time_s"] >= 0
    assert 0 < summary["contact_fraction"] < 1 and summary["peak_pressure_kpa"] > 0
    assert set(summary["error_parts"]) >= {"solver", "discretisation"}
    _fails([*SPHERE, "--out", str(out)], capsys, "exists and is not empty; choose a new folder, or add --force")
    assert main([*SPHERE, "--out", str(out), "--force", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["files"]  # rewritten


def test_plane_strain_sinusoid_matches_westergaard(tmp_path, capsys):
    """A periodic sinusoid below full contact: the contact width against Westergaard's closed form."""
    assert main(["contact", "sinusoid:A=5um,p=1mm", "--periodic", "--plane-strain", "--mean-pressure", "3kPa",
                 "--grid", "256", "--out", str(tmp_path / "o"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    p_star = np.pi * (1e6 / 0.75) * 5e-6 / 1e-3
    half_width = np.arcsin(np.sqrt(3e3 / p_star)) / np.pi * 1e-3  # sin^2(pi a / L) = p / p*
    assert summary["contact_length_mm"] * 1e-3 == pytest.approx(2 * half_width, abs=2 * 1e-3 / 256)
    assert summary["normal_force_n_per_m"] == pytest.approx(3e3 * 1e-3, rel=1e-9)


def test_height_map_file_and_scene(tmp_path, capsys):
    """A .npy height map pressed by a finger, and a scene file: both run and report their source."""
    rng = np.random.default_rng(0)
    np.save(tmp_path / "plate.npy", rng.standard_normal((32, 32)) * 0.5)
    assert main(["contact", str(tmp_path / "plate.npy"), "--spacing", "80um", "--height-unit", "um",
                 "--finger-radius", "10mm", "--normal-force", "0.2N", "--out", str(tmp_path / "a"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["surface"] == "plate" and summary["shape"] == [32, 32]
    scene = tmp_path / "scene.toml"
    scene.write_text('name = "bump"\n[material]\nyoung_modulus = "1MPa"\n[surface]\nkind = "defect"\n'
                     'shape = "bump"\nsize = "1mm"\nheight = "10um"\n[contact]\nnormal_force = "0.2N"\n'
                     'finger_radius = "10mm"\n[sensors]\nquantity = "strain"\ncomponents = ["zz"]\ndepth = "1mm"\n'
                     '[sensors.grid]\nnx = 1\nny = 1\nspacing_x = "1mm"\n[scan]\nspeed = "0mm/s"\n'
                     'duration = "0.1s"\nsampling_rate = "10Hz"\n')
    assert main(["contact", str(scene), "--grid", "32", "--out", str(tmp_path / "b"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["surface"] == "bump" and summary["normal_force_n"] == pytest.approx(0.2, rel=1e-9)
    assert any("finger R = 10 mm" in line for line in summary["computed"])


def test_partial_slip_reports_the_stick_radius(tmp_path, capsys):
    """Cattaneo-Mindlin at nu = 1/2: c = a (1 - Q / (mu P))^(1/3) within two grid spacings; the map is written."""
    out = tmp_path / "o"
    assert main([*SPHERE, "--friction", "0.5", "--condition", "partial", "--tangential-force", "0.125N",
                 "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    a = (3 * 0.5 * 10e-3 / (4 * 1e6 / 0.75)) ** (1 / 3)
    dx = 6 * a / 32  # the default grid spans 3 contact diameters
    assert summary["stick_radius_mm"] * 1e-3 == pytest.approx(a * 0.5 ** (1 / 3), abs=2 * dx)
    assert (out / "stick_slip.png").is_file()
    _fails([*SPHERE, "--friction", "0.5", "--condition", "partial", "--tangential-force", "0.3N",
            "--out", str(tmp_path / "p")], capsys, r"--tangential-force \(tangential_force\): .* exceeds the friction")
    _fails([*SPHERE, "--friction", "0.5", "--condition", "partial", "--out", str(tmp_path / "p")], capsys,
           "--tangential-force")
    assert not (tmp_path / "p").exists()  # a solve refused by the engine leaves no empty folder


def test_engine_refusals_name_the_option(tmp_path, capsys):
    _fails(["contact", "rough:rms=1um", "--periodic", "--mean-pressure", "3kPa", "--grid", "33",
            "--quiet", "--out", str(tmp_path / "o")], capsys,
           r"--grid \(gap\): a periodic grid needs an even number of nodes")
    from tactilab.cli.cmd_contact import as_option

    assert as_option("no colon here") == "no colon here"
    assert as_option("unknown_arg: text") == "unknown_arg: text"


def test_stuck_needs_no_friction_and_a_profile_is_a_cylinder(tmp_path, capsys):
    assert main(["contact", "sphere:R=10mm", "--plane-strain", "--normal-force", "100N/m", "--grid", "128",
                 "--condition", "stuck", "--tangential-force", "10N/m", "--out", str(tmp_path / "o"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["surface"] == "cylinder" and summary["friction"] == float("inf")
    a = np.sqrt(4 * 100 * 10e-3 / (np.pi * 1e6 / 0.75))  # Hertz half-width: stuck everywhere in contact
    assert summary["stick_radius_mm"] * 1e-3 == pytest.approx(a, abs=2 * 6 * a / 128)
    assert (tmp_path / "o" / "stick_slip.png").is_file()


@pytest.mark.parametrize("fmt", ["csv", "nc"])
def test_height_map_formats_with_coordinates(fmt, tmp_path, capsys):
    """A labelled .csv and a netCDF map carry their own grid: no --spacing, no --height-unit."""
    import xarray as xr

    heights = np.random.default_rng(1).standard_normal((16, 16)) * 0.5  # um
    coords = np.arange(16) * 0.1  # mm
    path = tmp_path / f"plate.{fmt}"
    if fmt == "csv":
        rows = [",".join(["height [um]"] + [f"{c:.1f}mm" for c in coords])]
        rows += [",".join([f"{y:.1f}mm"] + [repr(float(h)) for h in row]) for y, row in zip(coords, heights)]
        path.write_text("\n".join(rows) + "\n")
    else:
        xr.Dataset({"height": (("y", "x"), heights, {"units": "um"})},
                   coords={"x": ("x", coords, {"units": "mm"}), "y": ("y", coords, {"units": "mm"})}
                   ).to_netcdf(path, engine="h5netcdf")
    assert main(["contact", str(path), "--finger-radius", "10mm", "--normal-force", "0.2N",
                 "--out", str(tmp_path / "o"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["shape"] == [16, 16] and "100 um" in summary["computed"][0]


def test_method_choices_are_the_engines(tmp_path, capsys):
    from tactilab.cli.cmd_contact import NORMAL_METHODS
    from tactilab.forward.contact import METHODS

    assert set(NORMAL_METHODS) == {"auto", *METHODS}
    assert main([*SPHERE, "--method", "polonsky_keer", "--out", str(tmp_path / "o"), "--json"]) == 0
    assert "normal method polonsky_keer" in json.loads(capsys.readouterr().out)["method"]
