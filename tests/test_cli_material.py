"""``--material FILE`` on stress, contact, simulate and synthesis: it replaces --young-modulus/--nu (both is an
error), a viscoelastic material's --time, and the refusals, each one line with exit status 2."""

from __future__ import annotations

import argparse
import json
import re

import numpy as np
import pytest
import xarray as xr

from tactilab.cli.main import main
from tactilab.cli.material_option import read_material_option
from tactilab.forward import HalfSpace
from tactilab.forward.skin import Prony

SLS = '[material]\nmodel = "sls"\nyoung_modulus = "100kPa"\ninstantaneous_modulus = "300kPa"\nrelaxation_time = "50ms"\n'
ELASTIC = '[material]\nyoung_modulus = "200kPa"\npoisson_ratio = 0.5\n'
LAYERED = '[material]\nlayers = [{thickness = "2mm", young_modulus = "100kPa"}]\nbase = "rigid"\n'


def _file(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def _fails(argv, capsys, match):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and re.search(match, err), err


def _load(tmp_path):
    x = (np.arange(32) - 16) * 1e-4
    path = tmp_path / "load.npz"
    np.savez(path, p=np.exp(-(x[None, :] ** 2 + x[:, None] ** 2) / 1e-7) * 1e4, spacing=1e-4)
    return str(path)


def test_material_with_young_modulus_or_nu_is_an_error(tmp_path):
    path = _file(tmp_path, ELASTIC, "m.toml")
    args = argparse.Namespace(material=path, young_modulus="1MPa", nu=None)
    with pytest.raises(ValueError, match=r"--material: .* but --young-modulus was given too; drop --young-modulus"):
        read_material_option(args)
    args = argparse.Namespace(material=path, young_modulus="1MPa", nu=0.4)
    with pytest.raises(ValueError, match=r"--young-modulus and --nu were given too"):
        read_material_option(args)
    assert read_material_option(argparse.Namespace(material=None, young_modulus="1MPa", nu=0.4)) is None


@pytest.mark.parametrize("command", [
    ["stress", "LOAD", "--depth", "1mm", "--nu", "0.5"],
    ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--young-modulus", "1MPa"],
    ["synthesis", "--depth", "1mm", "--young-modulus", "1MPa"],
])
def test_every_command_refuses_both(tmp_path, capsys, command):
    argv = [_load(tmp_path) if a == "LOAD" else a for a in command]
    _fails([*argv, "--material", _file(tmp_path, ELASTIC, "m.toml")], capsys, r"--material: the material file sets")


def test_stress_with_an_elastic_material_equals_the_options(tmp_path):
    load = _load(tmp_path)
    assert main(["stress", load, "--depth", "1mm", "--components", "zz", "--material", _file(tmp_path, ELASTIC, "m.toml"),
                 "--out", str(tmp_path / "a"), "--json"]) == 0
    assert main(["stress", load, "--depth", "1mm", "--components", "zz", "--young-modulus", "200kPa", "--out",
                 str(tmp_path / "b"), "--json"]) == 0
    with xr.open_dataset(tmp_path / "a" / "field.nc", engine="h5netcdf") as a, \
            xr.open_dataset(tmp_path / "b" / "field.nc", engine="h5netcdf") as b:
        np.testing.assert_array_equal(a["strain"].values, b["strain"].values)


def test_stress_with_a_viscoelastic_material_creeps_with_time(tmp_path, capsys):
    """Tractions held for t: the strain is the instantaneous one times J(t) / J(0) (SLS written out)."""
    load = _load(tmp_path)
    path = _file(tmp_path, SLS, "sls.toml")
    for name, time in (("t0", "0ms"), ("t1", "70ms")):
        assert main(["stress", load, "--depth", "1mm", "--components", "zz", "--material", path, "--time", time,
                     "--out", str(tmp_path / name), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert any("1/J(t)" in line for line in summary["computed"])
    ratio = 3e5 * (1 / 1e5 - (1 / 1e5 - 1 / 3e5) * np.exp(-0.07 * 1e5 / (0.05 * 3e5)))
    with xr.open_dataset(tmp_path / "t0" / "field.nc", engine="h5netcdf") as a, \
            xr.open_dataset(tmp_path / "t1" / "field.nc", engine="h5netcdf") as b:
        np.testing.assert_allclose(b["strain"].values, ratio * a["strain"].values, rtol=1e-10,
                                   atol=1e-12 * float(np.abs(a["strain"]).max()))


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_contact_with_a_viscoelastic_material_grows_to_the_relaxed_limit(tmp_path, capsys):
    path = _file(tmp_path, SLS, "sls.toml")
    base = ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--grid-spacing", "0.2mm",
            "--quiet", "--json"]
    areas = []
    for name, extra in (("now", ["--material", path]), ("later", ["--material", path, "--time", "1s", "--depth", "1mm"]),
                        ("relaxed", ["--young-modulus", "100kPa"])):
        assert main([*base, *extra, "--out", str(tmp_path / name)]) == 0
        areas.append(json.loads(capsys.readouterr().out)["contact_area_mm2"])
    assert (tmp_path / "later" / "strain.nc").exists()
    # Lee-Radok: a^3 grows with J(t): from the glassy (1/3 the relaxed compliance) towards the relaxed
    assert areas[0] < areas[1] <= areas[2]
    assert areas[0] == pytest.approx(areas[2] / 3 ** (2 / 3), rel=0.15)  # 9 nodes across the radius
    assert areas[1] == pytest.approx(areas[2], rel=0.05)


def test_stress_time_refusals(tmp_path, capsys):
    load = _load(tmp_path)
    _fails(["stress", load, "--depth", "1mm", "--time", "70ms", "--out", str(tmp_path / "a")], capsys,
           r"--time: only a viscoelastic --material")
    _fails(["stress", load, "--depth", "1mm", "--time", "70ms", "--material", _file(tmp_path, ELASTIC, "m.toml"),
            "--out", str(tmp_path / "b")], capsys, r"--time: only a viscoelastic --material")
    _fails(["stress", load, "--depth", "1mm", "--time=-5ms", "--material", _file(tmp_path, SLS, "s.toml"),
            "--out", str(tmp_path / "c")], capsys, r"--time: must be >= 0")


def test_contact_takes_a_scenes_viscoelastic_material(tmp_path, capsys):
    """A scene whose [material] is viscoelastic is solved on that skin (not on its relaxed modulus alone)."""
    from tactilab.data_schemas import example_path

    text = example_path("fingertip_defect").read_text()
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace('young_modulus = "1MPa"', 'model = "sls"\nyoung_modulus = "1MPa"\n'
                                  'instantaneous_modulus = "3MPa"\nrelaxation_time = "50ms"'), encoding="utf-8")
    argv = ["contact", str(scene), "--grid", "32", "--quiet", "--json"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert any("viscoelastic skin (sls)" in line for line in summary["computed"])
    assert any("solved frictionless" in line for line in summary["dropped"])  # the scene's mu = 0.5
    _fails([*argv, "--young-modulus", "1MPa", "--out", str(tmp_path / "b")], capsys,
           r"--young-modulus, --nu: the scene's material is viscoelastic or layered")


def test_contact_viscoelastic_refusals(tmp_path, capsys):
    path = _file(tmp_path, SLS, "sls.toml")
    sphere = ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--quiet"]
    _fails([*sphere, "--time", "1s"], capsys, r"--time: only a viscoelastic --material")
    _fails([*sphere, "--material", path, "--time=-1s"], capsys, r"--time: must be >= 0")
    _fails([*sphere, "--material", path, "--condition", "sliding", "--friction", "0.5"], capsys,
           r"--condition: a viscoelastic --material is solved frictionless")
    _fails([*sphere, "--material", _file(tmp_path, "x", "m.txt")], capsys, r"a material file must end in .toml")


def test_synthesis_material_sets_the_modulus_and_refuses_what_it_cannot_design(tmp_path, capsys):
    common = ["synthesis", "--depth", "1mm", "--amplitude", "50um", "--no-sensitivity", "--json"]
    assert main([*common, "--material", _file(tmp_path, ELASTIC, "m.toml")]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main([*common, "--young-modulus", "200kPa"]) == 0
    b = json.loads(capsys.readouterr().out)
    assert a["designs"] == b["designs"] and a["designs"][0]["traction_kpa"] > 0
    assert any("skin from --material: E = 200 kPa" in line for line in a["computed"])
    _fails([*common, "--material", _file(tmp_path, LAYERED, "l.toml")], capsys,
           r"--material: a layered skin gets its optimal spacing here, not its matching traction")
    _fails([*common, "--material", _file(tmp_path, ELASTIC.replace("0.5", "0.4"), "n.toml")], capsys,
           r"assumes nu = 1/2")


def test_synthesis_matches_the_traction_at_the_drive_frequency(tmp_path, capsys):
    """Given tractions, the strain is J* times the stress: the matching traction scales with |E*(2 pi f)|
    (the SLS's written out by hand)."""
    path = _file(tmp_path, SLS, "sls.toml")
    common = ["synthesis", "--depth", "1mm", "--amplitude", "50um", "--no-sensitivity", "--json"]
    assert main([*common, "--material", path, "--drive-frequency", "10Hz"]) == 0
    driven = json.loads(capsys.readouterr().out)
    assert main([*common, "--material", path]) == 0
    quasi_static = json.loads(capsys.readouterr().out)
    w = 2 * np.pi * 10.0
    gain = abs(1e5 + 2e5 * 1j * w * 0.05 / (1 + 1j * w * 0.05)) / 1e5
    assert driven["designs"][0]["traction_kpa"] == pytest.approx(gain * quasi_static["designs"][0]["traction_kpa"],
                                                                 rel=1e-12)
    assert any("the strain lags the traction by" in line for line in driven["computed"])
    _fails([*common, "--drive-frequency", "10Hz", "--young-modulus", "1MPa"], capsys,
           r"--drive-frequency: only a viscoelastic --material")
    _fails([*common, "--material", path, "--drive-frequency=-1Hz"], capsys, r"--drive-frequency: must be >= 0 Hz")


def test_synthesis_designs_on_a_layered_material(tmp_path, capsys, monkeypatch):
    """The layered skin reaches the design: the CLI's optimum is optimal_half_spacing(..., skin=the layers)."""
    from tactilab.forward import Layer, LayeredHalfSpace, synthesis

    original = synthesis.optimal_half_spacing
    seen = []

    def quick(*args, **kwargs):  # a coarse search grid: the wiring is under test, not the optimum
        seen.append(kwargs.get("skin"))
        return original(*args, grid_points=20, **kwargs)

    monkeypatch.setattr(synthesis, "optimal_half_spacing", quick)
    assert main(["synthesis", "--depth", "1mm", "--no-sensitivity", "--json", "--material",
                 _file(tmp_path, LAYERED, "l.toml")]) == 0
    row = json.loads(capsys.readouterr().out)["designs"][0]
    skin = LayeredHalfSpace([Layer(2e-3, 1e5, 0.5)])
    assert repr(seen[0]) == repr(skin)
    assert row["d_mm"] == pytest.approx(original(1e-3, grid_points=20, skin=skin).d * 1e3, rel=1e-12)
    _fails(["synthesis", "--depth", "1mm", "--workers", "2", "--material", _file(tmp_path, LAYERED, "l.toml")],
           capsys, r"--workers/--scheduler: the batch design table is for the half-space")


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_simulate_takes_the_material_and_refuses_viscoelastic_layers(tmp_path, capsys):
    """Elastic layers simulate through the solved contact (tests/test_scene_layered.py); viscoelastic ones
    are refused in one line."""
    from tactilab.data_schemas import example_path

    scene = str(example_path("sliding_grating"))
    visco_layers = ('[material]\nlayers = [{thickness = "2mm", young_modulus = "100kPa", '
                    'terms = [["200kPa", "70ms"]]}]\nbase = "rigid"\n')
    _fails(["simulate", scene, "--material", _file(tmp_path, visco_layers, "l.toml"), "--out", str(tmp_path / "x"),
            "--quiet"], capsys, r"--material: a scene simulation takes an elastic or viscoelastic half-space or "
                                r"elastic layers, got viscoelastic layers")
    assert main(["simulate", scene, "--material", _file(tmp_path, SLS, "s.toml"), "--out", str(tmp_path / "s"),
                 "--quiet", "--no-plots", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert any("relaxed modulus" in line for line in summary["computed"])


def test_stress_and_contact_with_a_layered_material(tmp_path, capsys):
    """A 2 mm layer on bone is stiffer than the half-space of its modulus: a smaller contact."""
    path = _file(tmp_path, LAYERED, "l.toml")
    load = _load(tmp_path)
    assert main(["stress", load, "--depth", "1mm", "--components", "zz", "--material", path, "--quantity", "stress",
                 "--out", str(tmp_path / "s"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert any("layered skin: 2 mm of E = 100 kPa on a rigid base" in line for line in summary["computed"])
    _fails(["stress", load, "--depth", "1mm", "--material", path, "--method", "spectral", "--out",
            str(tmp_path / "t")], capsys, r"--method: a layered --material has its own solver")
    sphere = ["contact", "sphere:R=10mm", "--normal-force", "0.1N", "--grid", "32", "--grid-spacing", "0.2mm",
              "--quiet", "--json"]
    assert main([*sphere, "--material", path, "--out", str(tmp_path / "c1")]) == 0
    layered = json.loads(capsys.readouterr().out)["contact_area_mm2"]
    assert main([*sphere, "--young-modulus", "100kPa", "--out", str(tmp_path / "c2")]) == 0
    assert layered < json.loads(capsys.readouterr().out)["contact_area_mm2"]


def test_the_viscoelastic_stress_equals_the_library(tmp_path):
    """The option's skin is ViscoelasticHalfSpace.at(t): E = 1 / J(t)."""
    skin = HalfSpace(1 / float(Prony.sls(1e5, 3e5, 0.05).creep_compliance(0.07)))
    assert skin.E == pytest.approx(1 / (1 / 1e5 - (1 / 1e5 - 1 / 3e5) * np.exp(-0.07 * 1e5 / (0.05 * 3e5))))
