"""Every command that writes refuses to replace an earlier run's output without ``--force``; ``experiment
fit`` and ``compare`` name their default figures after the session, so a second session in the same folder
keeps the first's."""

from __future__ import annotations

import pytest

from tactilab.cli.main import main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments import SimulatedDisplay, new_session
from tactilab.experiments.modelling.models import TransductionModel
from tactilab.experiments.session.responses import SimulatedObserver

METAMER = ["metamer", "--target", "sinusoid:A=0.5mm,p=4mm", "--receptors", "21", "--scan", "1", "--json"]
DESIGN = '[[trials]]\namplitude_m = "0.3um"\npitch_m = "2mm"\nspeed_m_per_s = "20mm/s"\nn = 50\n'


def test_metamer_refuses_a_non_empty_out_without_force(tmp_path, capsys):
    out = tmp_path / "m"
    assert main([*METAMER, "--out", str(out)]) == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert main([*METAMER, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--out: the folder" in err and "exists and is not empty" in err and "add --force" in err
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before  # nothing replaced
    assert main([*METAMER, "--out", str(out), "--force"]) == 0


def test_experiment_power_refuses_an_existing_png_without_force(tmp_path, capsys):
    (tmp_path / "d.toml").write_text(DESIGN)
    argv = ["experiment", "power", "--true", "zx@1mm", "--rival", "zx@3mm", "--design", str(tmp_path / "d.toml"),
            "--out", str(tmp_path), "--json"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv) == 2
    assert "power.png already exists; export to another folder, or add --force" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 0


def _session(folder, subject: str):
    protocol = Protocol.model_validate(dict(
        name="amp", seed=2, task=dict(kind="2ifc"),
        stimulus=dict(amplitude_m="1um", pitch_m="4mm", speed_m_per_s="20mm/s", duration_s="50ms"),
        procedure=dict(method="constant_stimuli", parameter="amplitude_m", levels=["0.2um", "0.8um", "3.2um"],
                       repeats_per_block=2, n_blocks=2)))
    observer = SimulatedObserver.from_model(protocol, TransductionModel("zx@1mm"), threshold_strain=1e-4, seed=2)
    path = folder / f"sub-{subject}_ses-01_task-amp.sqlite"
    new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row()), observer, subject=subject,
                realtime=False)
    return path


def test_experiment_fit_keeps_each_sessions_figure(tmp_path, capsys):
    first, second = _session(tmp_path, "S01"), _session(tmp_path, "S02")
    assert main(["experiment", "fit", str(first), "--json"]) == 0
    figure = tmp_path / "sub-S01_ses-01_task-amp_fit_01.png"
    stamp = figure.stat().st_mtime_ns
    assert main(["experiment", "fit", str(second), "--json"]) == 0  # was fit_01.png: replaced the first's
    assert (tmp_path / "sub-S02_ses-01_task-amp_fit_01.png").is_file() and figure.stat().st_mtime_ns == stamp
    capsys.readouterr()
    assert main(["experiment", "fit", str(first), "--json"]) == 2  # the same session again: refused
    assert "sub-S01_ses-01_task-amp_fit_01.png already exists" in capsys.readouterr().err
    assert figure.stat().st_mtime_ns == stamp
    assert main(["experiment", "fit", str(first), "--json", "--force"]) == 0
    assert main(["experiment", "fit", str(first), str(second), "--out", str(tmp_path / "figs"), "--json"]) == 0
    assert (tmp_path / "figs" / "fit_01.png").is_file()
