"""A recording states the interface model it was made with; `tactilab simulate` prints it and `tactilab
invert` warns in one line when it assumes another (data_schemas/interface_model.py, forward/scene_model_files.py)."""

from __future__ import annotations

import pytest

from tactilab.cli.cmd_invert import _warn_model
from tactilab.cli.common import PRINTED_WARNINGS, RunReport
from tactilab.cli.main import main
from tactilab.data_schemas import Recording, read_recording
from tactilab.data_schemas.interface_model import model_mismatch, model_statement, recording_model

CELL = """
name = "cell"
description = "a sinusoid pressed at 0.3 p*"
[material]
young_modulus = "1MPa"
poisson_ratio = 0.5
[surface]
kind = "sinusoidal_grating"
period = "1mm"
amplitude = "2um"
[contact]
mean_pressure = "2.5kPa"
friction_coefficient = 0.3
{model}
[sensors]
quantity = "strain"
components = ["zz", "zx"]
depth = "0.3mm"
positions = [["0mm", "0mm"], ["0.25mm", "0mm"]]
[scan]
speed = "10mm/s"
duration = "0.05s"
sampling_rate = "400Hz"
onset = "10ms"
"""


def _cell(tmp_path, model=""):
    path = tmp_path / "cell.toml"
    path.write_text(CELL.format(model=model))
    return path


@pytest.mark.parametrize("fmt", ["netcdf", "parquet"])
def test_simulate_states_and_prints_the_model(tmp_path, capsys, fmt):
    out = tmp_path / "out"
    assert main(["simulate", str(_cell(tmp_path)), "--out", str(out), "--quiet", "--no-plots", "--format", fmt]) == 0
    text = capsys.readouterr().out
    assert "interface model: exact (auto: p_bar/p* = 0.298 (mean pressure below the texture's full-contact" in text
    assert "model errors: linear" in text and "measured on every frame against the exact model" in text
    path = out / ("recording.nc" if fmt == "netcdf" else "recording.parquet")
    stated = recording_model(read_recording(path), path)
    assert stated["model"] == "exact" and stated["tol"] == 0.01
    assert stated["errors"]["linear"] > 0.01 and stated["errors"]["modulation"] > 0.01


def test_simulate_honours_an_explicit_model(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(_cell(tmp_path, 'model = "linear"')), "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "interface model: linear (the scene's [contact] model)" in text
    assert "a priori (no frame solved exactly)" in text
    assert recording_model(read_recording(out / "recording.nc"), out / "recording.nc")["model"] == "linear"


def _recording(description):
    return Recording(values=[[[0.0]]], sampling_rate_hz=100.0, sensor_ids=("s0",), components=("zz",),
                     quantity="stress", description=description)


def test_the_statement_round_trips_through_the_description():
    text = "a scan " + model_statement("exact", 0.01, {"linear": 0.31, "modulation": 0.5}, "measured on every frame")
    stated = recording_model(_recording(text))
    assert stated == {"model": "exact", "tol": 0.01, "errors": {"linear": 0.31, "modulation": 0.5},
                      "basis": "measured on every frame"}
    assert recording_model(_recording("no statement")) is None


def test_invert_warns_in_one_line_naming_both_models_and_the_error(capsys):
    PRINTED_WARNINGS.clear()
    rec = _recording(model_statement("exact", 0.01, {"linear": 0.31, "modulation": 0.5}, "measured on every frame"))
    report = RunReport("invert")
    _warn_model(report, rec, None)
    assert len(report.warnings) == 1 and "\n" not in report.warnings[0]  # the summary repeats it
    line = report.warnings[0]
    assert "'exact'" in line and "'modulation'" in line and "0.5 of the signal" in line
    assert capsys.readouterr().err.strip() == f"tactilab invert: warning: {line}"
    PRINTED_WARNINGS.clear()
    quiet = RunReport("invert")
    _warn_model(quiet, _recording(model_statement("modulation", 0.01, {}, "not estimated")), None)
    _warn_model(quiet, _recording("an older recording"), None)
    assert quiet.warnings == []


def test_a_mismatch_without_an_error_says_so():
    line = model_mismatch({"model": "exact", "tol": 0.01, "errors": {}, "basis": ""}, "modulation", "the inversion")
    assert "gives no error of the modulation model" in line


def test_tactilab_contact_refuses_a_periodic_cell_scene(tmp_path, capsys):
    assert main(["contact", str(_cell(tmp_path))]) == 2
    assert "is a periodic cell (mean_pressure) without a finger" in capsys.readouterr().err


def test_a_batch_inversion_warns_once_for_its_recordings(tmp_path, capsys):
    from tactilab.cli.batch_options import _warn_models

    for i, model in enumerate(("exact", "exact", "modulation")):
        errors = {"modulation": 0.3 + i / 10} if model == "exact" else {}
        _recording("scan " + model_statement(model, 0.01, errors, "measured")).save(tmp_path / f"r{i}.json")
    _warn_models(tmp_path)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "2 recording(s)" in err[0] and "2 with 'exact'" in err[0] and "0.4 of the signal" in err[0]


def test_an_explicit_exact_model_states_the_cheap_models_errors(tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(_cell(tmp_path, 'model = "exact"')), "--out", str(out), "--quiet", "--no-plots"]) == 0
    stated = recording_model(read_recording(out / "recording.nc"), out / "recording.nc")
    assert stated["model"] == "exact" and stated["basis"] == "measured on every frame against the exact model"
    assert set(stated["errors"]) == {"linear", "modulation"}


def test_simulate_json_summary_carries_the_model(tmp_path, capsys):
    import json

    assert main(["simulate", str(_cell(tmp_path)), "--out", str(tmp_path / "o"), "--no-plots", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["interface_model"] == "exact" and data["interface_model_tol"] == 0.01
    assert set(data["interface_model_errors"]) == {"linear", "modulation"}
