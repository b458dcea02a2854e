"""The analysis and batch commands are reachable through the real ``tactilab`` dispatcher."""

from __future__ import annotations

from pathlib import Path

from tactilab.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def test_experiment_power_through_the_dispatcher(tmp_path, capsys):
    design = tmp_path / "d.toml"
    design.write_text('[[trials]]\namplitude_m = "0.3um"\npitch_m = "2mm"\nspeed_m_per_s = "20mm/s"\nn = 50\n'
                      '[[trials]]\namplitude_m = "1.2um"\npitch_m = "8mm"\nspeed_m_per_s = "20mm/s"\nn = 50\n')
    assert main(["experiment", "power", "--true", "zx@1mm", "--rival", "zx@3mm", "--design", str(design),
                 "--out", str(tmp_path)]) == 0
    assert "nats/trial" in capsys.readouterr().out


def test_experiment_fit_of_a_missing_session_is_one_line(capsys):
    assert main(["experiment", "fit", "/nonexistent/s.sqlite"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "session: no session file" in err[0]


def test_invert_needs_a_recording_or_a_batch_folder(capsys):
    scene = str(ROOT / "examples" / "biomimetic_finger_defect.toml")
    assert main(["invert", "--scene", scene]) == 2
    assert capsys.readouterr().err.strip() == (
        "tactilab invert: error: recording: give one recording file, or --batch DIR for a folder of them")
    assert main(["invert", "--scene", scene, "--batch", "/nonexistent-folder", "--workers", "0"]) == 2
    assert "--batch: must be a folder of recording files" in capsys.readouterr().err
