"""``experiment fit | power`` through cli/experiment_analysis.py (argparse, as the dispatcher calls it)."""

from __future__ import annotations

import argparse

import pytest

from tactilab.cli.experiment_analysis import add_subcommands
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, new_session
from tactilab.experiments.modelling.models import TransductionModel
from tactilab.experiments.session.responses import SimulatedObserver

DESIGN = """
[[trials]]
amplitude_m = "0.3um"
pitch_m = "2mm"
speed_m_per_s = "20mm/s"
n = 50
[[trials]]
amplitude_m = "0.3um"
pitch_m = "8mm"
speed_m_per_s = "20mm/s"
n = 50
[[trials]]
amplitude_m = "1.2um"
pitch_m = "8mm"
speed_m_per_s = "20mm/s"
n = 50
"""


def _run(argv):
    parser = argparse.ArgumentParser()
    add_subcommands(parser.add_subparsers(dest="action"))
    args = parser.parse_args(argv)
    return args._run(args)


def test_power_prints_a_table_and_writes_a_png(tmp_path, capsys):
    (tmp_path / "d.toml").write_text(DESIGN)
    assert _run(["power", "--true", "zx@1mm", "--rival", "zx@3mm", "--design", str(tmp_path / "d.toml"),
                 "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "nats/trial" in out and "trials for z = 4:" in out and (tmp_path / "power.png").stat().st_size > 10_000
    assert _run(["power", "--true", "zx@1mm", "--rival", "xx@1mm", "--design", str(tmp_path / "d.toml"),
                 "--out", str(tmp_path), "--force"]) == 0  # the folder holds the first run's power.png
    assert "never (identical predictions on this design)" in capsys.readouterr().out


def test_fit_per_condition(tmp_path, capsys):
    protocol = Protocol.model_validate(dict(
        name="amp", seed=2, task=dict(kind="2ifc"),
        stimulus=dict(amplitude_m="1um", pitch_m="4mm", speed_m_per_s="20mm/s", duration_s="50ms"),
        procedure=dict(method="constant_stimuli", parameter="amplitude_m",
                       levels=[f"{a}um" for a in (0.1, 0.2, 0.4, 0.8, 1.6)], repeats_per_block=3, n_blocks=4)))
    observer = SimulatedObserver.from_model(protocol, TransductionModel("zx@1mm"), threshold_strain=1e-4, seed=2)
    path = tmp_path / "s.sqlite"
    new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row()), observer, subject="S01",
                realtime=False)
    from tactilab.experiments.modelling.analysis import fit_summary

    (line,) = fit_summary(path)
    assert line.startswith("amplitude threshold ") and "95 % interval" in line and "60 trials" in line
    assert _run(["fit", str(path), "--out", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "sinusoid, pitch 4 mm, speed 20 mm/s" in out and " um " in out
    assert (tmp_path / "figs" / "fit_01.png").stat().st_size > 10_000


@pytest.mark.parametrize("argv, match", [
    (["power", "--true", "zx@1mm", "--rival", "xx@1mm", "--design", "/nonexistent.toml"], "design: no design file"),
    (["fit", "/nonexistent.sqlite"], "session: no session file"),
    (["compare", "/nonexistent.sqlite", "--model", "zx@1mm"], "model: give at least two hypotheses"),
    (["compare", "/nonexistent.sqlite", "--model", "zx@1mm", "--model", "zx@1mm"], "model: each hypothesis once"),
])
def test_one_line_errors(argv, match):
    with pytest.raises(ValueError, match=match):
        _run(argv)


def test_design_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    for text, match in (("trials = 3", r"needs \[\[trials\]\] tables"), ("[[trials]\n", "not valid TOML"),
                        ('[[trials]]\namplitude_m = "1um"\npitch_m = "2mm"\nspeed_m_per_s = "0"\n', "needs n =")):
        bad.write_text(text)
        with pytest.raises(ValueError, match=match):
            _run(["power", "--true", "zx@1mm", "--rival", "xx@1mm", "--design", str(bad)])
