"""``--workers`` / ``--scheduler`` and ``--json`` on the batch commands, through the real dispatcher:
``experiment compare`` (per-subject fits), ``experiment power --seeds``, ``synthesis``, ``metamer --scan-*``.

Oracles: the JSON summaries equal the library's batch results; the same command on a running
scheduler gives the same numbers as ``--workers 0``; a rerun resumes; bad options are one-line
errors (exit 2).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.core import batch as B
from tactilab.core import task_rng
from tactilab.data_schemas import DisplayDescription, Protocol
from tactilab.experiments import SimulatedDisplay, TransductionModel, new_session, power_analysis
from tactilab.experiments.modelling import VERDICTS
from tactilab.experiments.modelling.analysis import read_design
from tactilab.experiments.modelling.batch import sessions_by_subject
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.forward import design_table

DESIGN = "".join(f'[[trials]]\namplitude_m = "{a}um"\npitch_m = "{p}mm"\nspeed_m_per_s = "20mm/s"\nn = 50\n'
                 for a in (0.3, 1.2) for p in (1, 2, 8))


@pytest.fixture(scope="module")
def client():
    import distributed

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  env=dict(B.ONE_THREAD_ENV)) as cluster, distributed.Client(cluster) as cl:
        yield cl


def _json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def _session(path, subject, seed):
    protocol = Protocol.model_validate(dict(
        name="amp", seed=seed, task=dict(kind="2ifc"),
        stimulus=dict(amplitude_m="1um", pitch_m="4mm", speed_m_per_s="20mm/s", duration_s="50ms"),
        procedure=dict(method="constant_stimuli", parameter="amplitude_m",
                       levels=[f"{a}um" for a in (0.1, 0.2, 0.4, 0.8, 1.6)], repeats_per_block=2, n_blocks=3)))
    observer = SimulatedObserver.from_model(protocol, TransductionModel("zx@1mm"), threshold_strain=1e-4, seed=seed)
    new_session(protocol, path, SimulatedDisplay(DisplayDescription.braille_row()), observer, subject=subject,
                realtime=False)
    return str(path)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    root = tmp_path_factory.mktemp("sessions")
    return [_session(root / f"{s}-{i}.sqlite", s, seed) for seed, (s, i) in
            enumerate([("S01", 1), ("S02", 1), ("S01", 2)], start=1)]


@pytest.mark.slow
def test_experiment_compare_per_subject_serial_and_on_a_scheduler(sessions, tmp_path, capsys, client):
    argv = ["experiment", "compare", *sessions, "--model", "zx@1mm", "--model", "zx@3mm", "--seed", "2", "--json"]
    assert main([*argv, "--workers", "0", "--out", str(tmp_path / "w0")]) == 0
    serial = _json(capsys)
    assert set(serial["subjects"]) == {"S01", "S02"} and serial["n_run"] == 4 and serial["n_failed"] == 0
    verdicts = [serial["subjects"]["S01"][m]["verdict"] for m in ("zx@1mm", "zx@3mm")]
    assert verdicts == ["not identifiable on this design"] * 2  # one pitch: the depth only rescales the threshold
    assert all(serial["subjects"]["S01"][m]["reason"] for m in ("zx@1mm", "zx@3mm"))
    assert main([*argv, "--scheduler", client.scheduler.address, "--out", str(tmp_path / "remote")]) == 0
    remote = _json(capsys)
    assert remote["subjects"] == serial["subjects"]  # the same numbers, bit for bit (JSON floats round-trip)
    assert main([*argv, "--workers", "0", "--out", str(tmp_path / "w0")]) == 0
    again = _json(capsys)
    assert (again["n_run"], again["n_skipped"]) == (0, 4) and again["subjects"] == serial["subjects"]
    assert main([*argv[:-1], "--workers", "0", "--out", str(tmp_path / "w0")]) == 0
    text = capsys.readouterr().out
    assert "subject S01" in text and "subject S02" in text and "0 fit(s) run, 4 skipped (done before)" in text


def test_sessions_by_subject_groups_by_the_recorded_subject(sessions, tmp_path):
    grouped = sessions_by_subject(list(reversed(sessions)))
    assert grouped == {"S01": sorted([sessions[0], sessions[2]]), "S02": [sessions[1]]}
    with pytest.raises(ValueError, match="sessions: no session file at"):
        sessions_by_subject([tmp_path / "missing.sqlite"])
    with pytest.raises(ValueError, match="sessions: empty; give at least one session"):
        sessions_by_subject([])


def test_experiment_compare_pooled_json_and_errors(sessions, tmp_path, capsys):
    argv = ["experiment", "compare", sessions[0], "--model", "zx@1mm", "--model", "zx@3mm", "--method", "emcee",
            "--max-steps", "60"]
    assert main([*argv, "--out", str(tmp_path), "--json"]) == 0
    summary = _json(capsys)
    assert set(summary["models"]) == {"zx@1mm", "zx@3mm"} and summary["png"].endswith("compare.png")
    for row in summary["models"].values():  # 60 steps do not converge: no verdict, and what to do
        assert row["converged"] or row["verdict"] == "no verdict: fit not converged"
        assert row["converged"] or "--max-steps" in row["reason"]
    assert main([*argv[:5], "--max-steps", "60"]) == 2
    assert "--max-steps: only for --method emcee" in capsys.readouterr().err
    assert main([*argv[:5], "--workers", "0", "--out", str(tmp_path / "b")]) == 2
    assert "--model: give two or more different hypotheses" in capsys.readouterr().err
    assert main([*argv, "--max-steps", "0"]) == 2
    assert "--max-steps: must be >= 1 step, got 0" in capsys.readouterr().err


def test_experiment_power_simulated_sweep_json(tmp_path, capsys):
    design = tmp_path / "d.toml"
    design.write_text(DESIGN)
    argv = ["experiment", "power", "--true", "zx@1mm", "--rival", "zx@3mm", "--design", str(design),
            "--out", str(tmp_path), "--threshold", "2e-4"]
    assert main([*argv, "--seeds", "2", "--trials", "50,200", "--repeats", "3", "--seed", "4", "--workers", "0",
                 "--json"]) == 0
    summary = _json(capsys)
    sim = summary["simulated"]
    assert sim["n_trials"] == [50, 200] and sim["n_run"] == 4 and len(sim["p_select"]) == 2
    design_list = read_design(design)
    direct = power_analysis(TransductionModel("zx@1mm"), dict(threshold_strain=2e-4, exponent=1.0, lapse=0.02),
                            TransductionModel("zx@3mm"), design_list, method="simulate", n_repeats=3,
                            rng=task_rng(4, "seed-0001/n-200"))
    assert sim["p_select"][1][1] == direct.p_select(200, z=4.0)
    assert summary["mu_nats_per_trial"] > 0 and summary["png"].endswith("power.png")
    assert main([*argv, "--workers", "2"]) == 2
    assert "--seeds: --workers, --scheduler and --trials belong to the simulated sweep" in capsys.readouterr().err
    assert main([*argv, "--seeds", "1", "--trials", "50,x"]) == 2
    assert "--trials: expected comma-separated trial counts" in capsys.readouterr().err
    assert main([*argv, "--seeds", "1", "--repeats", "0"]) == 2
    assert "--repeats: must be >= 1 simulated experiment, got 0" in capsys.readouterr().err


def test_synthesis_design_table_as_a_batch(tmp_path, capsys):
    argv = ["synthesis", "--depth", "1mm,2mm", "--sensitivity-widths", "8mm", "--sensitivity-pairs", "3,5",
            "--workers", "0", "--out", str(tmp_path)]
    assert main([*argv, "--json"]) == 0
    rows = _json(capsys)["designs"]
    table = design_table([1e-3, 2e-3], [8e-3], [3, 5])
    assert len(rows) == 4
    for row, (_, ref) in zip(rows, table.iterrows()):
        assert row["d_mm"] == ref["d_m"] * 1e3 and row["pairs"] == ref["pairs"]
    assert main(argv) == 0
    assert "4 run" not in (text := capsys.readouterr().out) and "0 run, 4 skipped" in text
    assert main([*argv, "--amplitude", "50um", "--young-modulus", "200kPa"]) == 2
    assert "drop --amplitude and --traction-limit" in capsys.readouterr().err


@pytest.mark.slow  # a few seconds; the whole suite runs it
def test_metamer_scan_serial_and_on_a_scheduler(tmp_path, capsys, client):
    argv = ["metamer", "--target", "sinusoid:A=20um,p=4mm", "--scan-pitch", "2mm,4mm", "--scan-phase", "0,1.5",
            "--scan-display", "wh2008,stress2", "--receptors", "41", "--scan", "2", "--json"]
    assert main([*argv, "--out", str(tmp_path / "w0")]) == 0
    serial = _json(capsys)
    assert len(serial["points"]) == 8 and serial["n_run"] == 8 and all(p["finished"] for p in serial["points"])
    assert {p["display"] for p in serial["points"]} == {"WH2008", "STReSS2"}
    assert main([*argv, "--scheduler", client.scheduler.address, "--out", str(tmp_path / "remote")]) == 0
    assert _json(capsys)["points"] == serial["points"]
    assert main([*argv[:-1], "--out", str(tmp_path / "w0")]) == 0
    assert "0 point(s) run, 8 skipped" in capsys.readouterr().out
    assert main([*argv, "--scan-pitch=-2mm", "--out", str(tmp_path)]) == 2
    assert "--scan-pitch: must be finite and > 0 m" in capsys.readouterr().err


def test_experiment_fit_json(sessions, tmp_path, capsys):
    assert main(["experiment", "fit", sessions[0], "--out", str(tmp_path), "--json"]) == 0
    (row,) = _json(capsys)["conditions"]
    assert row["n_trials"] == 30 and row["unit"] == "um" and row["threshold_ci95"][0] < row["threshold"]
    assert np.isfinite(row["gof_p"]) and row["png"].endswith("fit_01.png")
