"""``--material`` with viscoelastic layers on stress, contact, synthesis and simulate.

Oracles: the Python API (``ViscoelasticLayeredHalfSpace.stress/strain`` under a step held for t, by the
recursive creep convolution), elastic layered material files holding the glassy and the relaxed
moduli (the contact's exact limits), and the design on the glassy layers (one relaxation shape: the
moduli keep their ratios, so the optimum does not move). Each refusal is one line with exit status 2.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import xarray as xr

from tactilab.cli.main import main
from tactilab.cli.material_option import read_time_option
from tactilab.data_schemas import read_material
from tactilab.forward import SurfaceLoad, skin_from_material

#: one relaxation shape: the dermis's Prony series is twice the pulp's
SHAPED = ('[material]\nlayers = [{thickness = "1mm", young_modulus = "0.4MPa", terms = [["2MPa", "4ms"], ["1MPa", "70ms"]]},'
          '\n  {thickness = "3mm", young_modulus = "0.2MPa", terms = [["1MPa", "4ms"], ["0.5MPa", "70ms"]]}]\n')
#: layers that relax differently (a fast dermis on a slower pulp)
DIFFER = ('[material]\nlayers = [{thickness = "1mm", young_modulus = "0.6MPa", terms = [["0.6MPa", "2ms"]]},'
          '\n  {thickness = "3mm", young_modulus = "0.2MPa", terms = [["1MPa", "4ms"], ["0.5MPa", "70ms"]]}]\n')
#: DIFFER's glassy and relaxed layers, as elastic material files
GLASSY = ('[material]\nlayers = [{thickness = "1mm", young_modulus = "1.2MPa"},'
          '\n  {thickness = "3mm", young_modulus = "1.7MPa"}]\n')
RELAXED = ('[material]\nlayers = [{thickness = "1mm", young_modulus = "0.6MPa"},'
           '\n  {thickness = "3mm", young_modulus = "0.2MPa"}]\n')


def _file(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def _fails(argv, capsys, match):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and re.search(match, err), err


def _load(tmp_path, periodic=False):
    x = (np.arange(32) - 16) * 1e-4
    p = np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) / 1e-7) * 1e4
    path = tmp_path / "load.npz"
    np.savez(path, p=p, qx=0.2 * p, spacing=1e-4, periodic=periodic)
    return str(path), SurfaceLoad(p=p, qx=0.2 * p, spacing=1e-4, periodic=periodic)


def _field(folder, quantity):
    with xr.open_dataset(folder / "field.nc", engine="h5netcdf") as ds:
        return ds[quantity].values


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_stress_of_a_held_load_on_layers_of_one_shape_is_the_library_field(tmp_path, capsys):
    """--time 70ms: the CLI's stress and strain equal ViscoelasticLayeredHalfSpace's under a step held 70 ms."""
    path = _file(tmp_path, SHAPED, "m.toml")
    npz, load = _load(tmp_path, periodic=True)  # periodic: no padded grid, a quick test
    skin = skin_from_material(read_material(path))
    for quantity in ("stress", "strain"):
        assert main(["stress", npz, "--depth", "0.5mm", "--depth", "2mm", "--material", path, "--time", "70ms",
                     "--quantity", quantity, "--out", str(tmp_path / quantity), "--json"]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert any("held for 70 ms: the elastic layers of moduli" in line for line in summary["computed"])
        api = getattr(skin, quantity)(load, [5e-4, 2e-3], [0.0, 0.07]).values[-1]
        mine = _field(tmp_path / quantity, quantity)
        assert np.abs(mine - api).max() <= 1e-12 * np.abs(api).max()


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_stress_on_layers_that_relax_differently_at_their_limits_and_refused_between(tmp_path, capsys):
    """0 and relaxed are the glassy and the relaxed layers for any layers (elastic files of those moduli);
    a time between needs one relaxation shape."""
    npz, _ = _load(tmp_path)
    common = ["stress", npz, "--depth", "1.5mm", "--components", "zz,zx", "--json"]
    for name, extra in (("now", ["--material", _file(tmp_path, DIFFER, "d.toml")]),
                        ("glassy", ["--material", _file(tmp_path, GLASSY, "g.toml")]),
                        ("late", ["--material", str(tmp_path / "d.toml"), "--time", "relaxed"]),
                        ("relaxed", ["--material", _file(tmp_path, RELAXED, "r.toml")])):
        assert main([*common, *extra, "--out", str(tmp_path / name)]) == 0
    capsys.readouterr()
    np.testing.assert_array_equal(_field(tmp_path / "now", "strain"), _field(tmp_path / "glassy", "strain"))
    np.testing.assert_array_equal(_field(tmp_path / "late", "strain"), _field(tmp_path / "relaxed", "strain"))
    _fails([*common, "--material", str(tmp_path / "d.toml"), "--time", "10ms", "--out", str(tmp_path / "x")], capsys,
           r"--time: a held load on viscoelastic layers at a time between 0 and relaxed needs every material to "
           r"relax with one shape .* layers\[1\] of the material differs; give --time 0ms")
    _fails([*common, "--material", str(tmp_path / "g.toml"), "--time", "relaxed", "--out", str(tmp_path / "y")], capsys,
           r"--time: only a viscoelastic --material \(model prony or sls, or layers with Prony terms\)")


def test_the_time_option_reads_relaxed_and_refuses_bad_times():
    assert read_time_option(None) is None and read_time_option("Relaxed") == np.inf
    assert read_time_option("70ms") == pytest.approx(0.07)
    with pytest.raises(ValueError, match=r"--time: must be >= 0 \(0 is the instant the load is applied\), got "
                                         r"'-5ms'; e.g. 70ms, or relaxed"):
        read_time_option("-5ms")
    with pytest.raises(ValueError, match=r"--time: .* has no unit"):
        read_time_option("5")


def test_contact_on_viscoelastic_layers_is_the_glassy_or_the_relaxed_elastic_contact(tmp_path, capsys):
    """Default: the elastic contact of the glassy layers (friction kept); relaxed: of the relaxed layers,
    frictionless; the same numbers as elastic material files of those moduli."""
    viscous = _file(tmp_path, DIFFER, "d.toml")
    sphere = ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--grid-spacing", "0.2mm",
              "--quiet", "--json"]
    runs = {}
    for name, extra in (("now", ["--material", viscous, "--friction", "0.5"]),
                        ("glassy", ["--material", _file(tmp_path, GLASSY, "g.toml"), "--friction", "0.5"]),
                        ("late", ["--material", viscous, "--time", "relaxed"]),
                        ("relaxed", ["--material", _file(tmp_path, RELAXED, "r.toml")])):
        assert main([*sphere, *extra, "--out", str(tmp_path / name)]) == 0
        runs[name] = json.loads(capsys.readouterr().out)
    for a, b in (("now", "glassy"), ("late", "relaxed")):
        for key in ("contact_area_mm2", "peak_pressure_kpa", "approach_um", "condition"):
            assert runs[a][key] == runs[b][key], key
    assert runs["now"]["condition"] == "sliding" and runs["late"]["condition"] == "frictionless"
    assert runs["now"]["contact_area_mm2"] < runs["late"]["contact_area_mm2"]
    assert any("the instantaneous contact, on the glassy elastic layers" in line for line in runs["now"]["computed"])
    _fails([*sphere, "--material", viscous, "--time", "200ms"], capsys,
           r"--time: the contact of viscoelastic layers is computed at its two exact limits, 0ms .* and relaxed")
    _fails([*sphere, "--material", viscous, "--time", "relaxed", "--friction", "0.5"], capsys,
           r"--time relaxed: the relaxed contact is the limit of the frictionless time-stepped contact .* "
           r"got --friction 0.5; drop --condition and --friction")


def test_contact_of_a_viscoelastic_halfspace_held_until_relaxed_is_the_relaxed_elastic_contact(tmp_path, capsys):
    sls = _file(tmp_path, '[material]\nmodel = "sls"\nyoung_modulus = "100kPa"\ninstantaneous_modulus = "300kPa"\n'
                          'relaxation_time = "50ms"\n', "s.toml")
    sphere = ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--grid-spacing", "0.2mm",
              "--quiet", "--json"]
    assert main([*sphere, "--material", sls, "--time", "relaxed", "--out", str(tmp_path / "a")]) == 0
    late = json.loads(capsys.readouterr().out)
    assert main([*sphere, "--young-modulus", "100kPa", "--out", str(tmp_path / "b")]) == 0
    assert late["contact_area_mm2"] == json.loads(capsys.readouterr().out)["contact_area_mm2"]


def test_synthesis_designs_viscoelastic_layers_on_their_relaxed_moduli(tmp_path, capsys, monkeypatch):
    """One relaxation shape: the relaxed design is the glassy one (the moduli keep their ratios); the summary
    says which case; --drive-frequency is refused."""
    from tactilab.forward import synthesis

    original = synthesis.optimal_half_spacing
    seen = []

    def quick(*args, **kwargs):  # a coarse search grid: the wiring is under test, the optimum in the forward tests
        seen.append(kwargs.get("skin"))
        return original(*args, grid_points=20, **kwargs)

    monkeypatch.setattr(synthesis, "optimal_half_spacing", quick)
    shaped = _file(tmp_path, SHAPED, "m.toml")
    assert main(["synthesis", "--depth", "1mm", "--no-sensitivity", "--json", "--material", shaped]) == 0
    summary = json.loads(capsys.readouterr().out)
    skin = skin_from_material(read_material(shaped))
    assert repr(seen[-1]) == repr(skin.relaxed)
    glassy = original(1e-3, grid_points=20, skin=skin.instantaneous).d
    assert summary["designs"][0]["d_mm"] == pytest.approx(glassy * 1e3, rel=1e-9)
    assert any("optimum holds at any drive rate" in line for line in summary["computed"])
    assert main(["synthesis", "--depth", "1mm", "--no-sensitivity", "--json", "--material",
                 _file(tmp_path, DIFFER, "d.toml")]) == 0
    assert any("the slow-drive limit" in line for line in json.loads(capsys.readouterr().out)["computed"])
    _fails(["synthesis", "--depth", "1mm", "--material", shaped, "--drive-frequency", "100Hz"], capsys,
           r"--drive-frequency: viscoelastic layers get their optimal spacing here, designed on their relaxed "
           r"moduli .*; drop --drive-frequency")


def test_simulate_refuses_viscoelastic_layers(tmp_path, capsys):
    from tactilab.data_schemas import example_path

    _fails(["simulate", str(example_path("sliding_grating")), "--material", _file(tmp_path, DIFFER, "d.toml"),
            "--out", str(tmp_path / "x"), "--quiet"], capsys,
           r"--material: a scene simulation takes an elastic or viscoelastic half-space or elastic layers, got "
           r"viscoelastic layers; give each layer its relaxed young_modulus without terms, or solve viscoelastic")
