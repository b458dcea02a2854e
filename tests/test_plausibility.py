"""Implausible values at the edges warn with the value and the usual range; --strict refuses them."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas.plausibility import PLAUSIBLE, PlausibilityWarning, base_quantity, check_plausible
from tactilab.data_schemas.units import to_si

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name,base", [
    ("--grid-spacing", "grid_spacing"), ("material.young_modulus", "young_modulus"),
    ("sensors.depth_m", "depth"), ("--watchdog", "watchdog"), ("tracks[0].start", "start"),
    ("display.young_modulus_pa", "young_modulus"),
])
def test_edge_names_reduce_to_their_quantity(name, base):
    assert base_quantity(name) == base


@pytest.mark.parametrize("quantity", sorted(PLAUSIBLE))
def test_each_quantity_warns_outside_its_range_only(quantity):
    low, high, usual = PLAUSIBLE[quantity]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_plausible((low + high) / 2, quantity)  # inside: silent
    with pytest.raises(PlausibilityWarning, match=rf"{quantity} = .* is outside the usual range \({usual}\); "
                                                  "check its unit"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_plausible(high * 10, quantity)


def test_to_si_warns_for_a_50_m_grid_and_a_1_pa_modulus():
    with pytest.warns(PlausibilityWarning, match=r"--grid-spacing = 50 m is outside the usual range"):
        to_si("50m", "length", name="--grid-spacing")
    with pytest.warns(PlausibilityWarning, match=r"--young-modulus = 1 Pa is outside .*1 kPa to 1 GPa"):
        to_si("1Pa", "pressure", name="--young-modulus")


def test_cli_prints_one_warning_line_and_strict_makes_it_an_error(tmp_path, capsys):
    load = str(ROOT / "examples" / "fingertip_load.toml")
    assert main(["stress", load, "--depth", "50mm", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["tactilab stress: warning: --depth = 0.05 m is outside the usual range "
                   "(receptor and sensor depths are 1 um to 20 mm); check its unit"]
    assert main(["--strict", "stress", load, "--depth", "50mm", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tactilab stress: error: --depth = 0.05 m is outside")
    assert not (tmp_path / "b" / "field.nc").exists()
