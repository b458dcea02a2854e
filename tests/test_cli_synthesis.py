"""``tactilab synthesis``: the printed design agrees with the library; bad options are one line."""

from __future__ import annotations

import pytest

from tactilab.cli import cmd_synthesis
from tactilab.cli.main import build_parser, main
from tactilab.forward import synthesis


def test_prints_design_and_sensitivity(capsys):
    status = main(["synthesis", "--depth", "2mm", "--amplitude", "50um", "--young-modulus", "200kPa",
                   "--traction-limit", "5kPa", "--sensitivity-widths", "8mm,12mm", "--sensitivity-pairs", "3,5"])
    out = capsys.readouterr().out
    assert status == 0
    design = synthesis.optimal_half_spacing(2e-3)
    assert f"{design.d * 1e3:8.4f}" in out
    a_max = synthesis.max_virtual_amplitude(5e3, None, None, 200e3, design)
    assert f"{a_max * 1e6:10.4g}" in out
    assert "sensitivity to the window width" in out and "sensitivity to the number of pairs" in out
    assert out.count("\n   2.000 ") >= 5  # 1 design row, 2 width rows, 2 pairs rows


def test_several_depths_print_a_scaling_fit(capsys):
    assert main(["synthesis", "--depth", "2mm,3mm", "--no-sensitivity"]) == 0
    out = capsys.readouterr().out
    assert "scaling with depth" not in out  # no sensitivity block requested
    assert main(["synthesis", "--depth", "2mm,3mm", "--sensitivity-widths", "10mm", "--sensitivity-pairs", "5"]) == 0
    assert "scaling with depth: d = " in capsys.readouterr().out


@pytest.mark.parametrize("argv, match", [
    (["--depth", "0mm"], "--depth: every depth must be finite and > 0 m"),
    (["--depth", "1kPa"], "--depth: unit 'kPa' measures pressure"),
    (["--depth", ","], "--depth: give at least one length"),
    (["--depth", "1mm", "--width=-2mm"], "--width: must be finite and > 0 m, got -0.002; give a positive value with a unit"),
    (["--depth", "1mm", "--pairs", "0"], "--pairs: the number of tractor pairs must be >= 1"),
    (["--depth", "1mm", "--pairs", "five"], "--pairs: expected integers"),
    (["--depth", "1mm", "--pairs", "3,5"], "--pairs: give one number of pairs"),
    (["--depth", "1mm", "--amplitude", "50um"], "--young-modulus: needed with --amplitude"),
    (["--depth", "1mm", "--young-modulus", "0kPa"], "--young-modulus: Young's modulus must be finite and > 0 Pa"),
    (["--depth", "1mm", "--young-modulus", "1kPa", "--traction-limit=-1kPa"], "--traction-limit: must be finite and > 0 Pa"),
    (["--depth", "1mm", "--footprint", "0mm"], "--footprint: must be finite and > 0 m"),
    (["--depth", "1mm", "--sensitivity-widths", "0mm"], "--sensitivity-widths: must be finite and > 0 m"),
])
def test_bad_options_raise_value_error_naming_the_option(argv, match):
    args = build_parser().parse_args(["synthesis", *argv])
    with pytest.raises(ValueError, match=match):
        cmd_synthesis.run(args)


def test_bad_option_is_one_line_and_exit_2(capsys):
    assert main(["synthesis", "--depth=-1mm"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--depth" in err
