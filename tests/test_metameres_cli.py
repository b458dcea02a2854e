"""``tactilab metamer``: printed numbers agree with the library; files are written; bad options are one line."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import DisplayDescription
from tactilab.inversion import SinusoidFamily, TractorFamily, metamer_pair


def test_prints_residual_dprime_and_loads(tmp_path, capsys):
    argv = ["metamer", "--target", "sinusoid:A=0.5mm,p=4mm,phase=1.5707963267948966", "--display", "wh2008",
            "--hypothesis", "xx,zx@1.25mm", "--noise", "1e-3", "--out", str(tmp_path), "--scan", "4", "--unbounded"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    fam = TractorFamily.from_display(DisplayDescription.wh2008(), 1.54e6)
    pair = metamer_pair(SinusoidFamily(4e-3, np.pi / 2).stimulus([0.5e-3]), fam, "xx,zx@1.25mm;noise=1e-3",
                        np.linspace(-5e-3, 5e-3, 201), bounds=None)
    assert f"relative residual {pair.relative_residual:.4g}" in out and f"d' = {pair.dprime:.4g}" in out
    assert f"+1 mm: {pair.params[5] * 1e-3:+.4f}" in out and "tractor loads (N/mm)" in out
    assert (tmp_path / "metamer_strain.png").stat().st_size > 1000
    assert (tmp_path / "metamer_spectrum.png").stat().st_size > 1000
    assert main(argv + ["--json", "--force"]) == 0  # the folder holds the first run's PNGs
    result = json.loads(capsys.readouterr().out)
    assert result["relative_residual"] == pytest.approx(pair.relative_residual, rel=1e-12)
    np.testing.assert_allclose(result["loads_n_per_m"], pair.params, rtol=1e-9)


def test_bounded_display_reports_loads_at_the_limit(tmp_path, capsys):
    assert main(["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--out", str(tmp_path), "--scan", "2"]) == 0
    out = capsys.readouterr().out
    assert "sit at their load limit (0.05 N/mm)" in out


def test_display_from_a_json_description(tmp_path, capsys):
    path = tmp_path / "row.json"
    DisplayDescription.wh2008(max_traction_pa=2e6, display_id="MyRow").save(path)
    assert main(["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--display", str(path), "--out", str(tmp_path / "o"),
                 "--scan", "2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["display"] == "MyRow" and result["load_limit_n_per_m"] == pytest.approx(2e3)
    assert max(abs(q) for q in result["loads_n_per_m"]) <= 2e3 * (1 + 1e-9)


@pytest.mark.parametrize("argv, match", [
    (["--target", "bump:A=1mm"], "--target: expected sinusoid:A=LENGTH,p=LENGTH"),
    (["--target", "sinusoid:A=1mm"], "--target: give both A= and p="),
    (["--target", "sinusoid:A=1mm,q=2mm"], "--target: unknown or repeated field 'q=2mm'"),
    (["--target", "sinusoid:A=1mm,p=0mm"], "--target p: the pitch must be > 0"),
    (["--target", "sinusoid:A=1kPa,p=4mm"], "--target A: unit 'kPa' measures pressure"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--display", "nope"], "--display: must be one of wh2008"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--hypothesis", "xx@1mm:gamma"], "hypothesis: unknown shear convention"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--noise", "0"], "--noise: must be finite and > 0, got 0.0; give a positive value"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--young-modulus", "1mm"], "--young-modulus: unit 'mm' measures length"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--receptors", "1"], "--receptors: must be >= 2"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--scan", "x"], "--scan: expected an integer >= 1"),
    (["--target", "sinusoid:A=1mm,p=4mm", "--window=-1mm"], "--window: must be finite and > 0 m"),
])
def test_bad_options_are_one_line(argv, match, capsys, tmp_path):
    assert main(["metamer", *argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert re.search(match, err)
