"""`tactilab experiment` run / resume / export / status, export formats, factory specs."""

from __future__ import annotations

import re

import contextlib
import json
import sqlite3
import sys
from pathlib import Path

import pandas as pd
import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.experiments import devices
from tactilab.experiments.session import factory
from tactilab.experiments.session.export import export_session, read_trials_csv, session_dataframe
from tactilab.experiments.session.recording import Recorder, RecordingError, SessionLog, _FileLock
from tactilab.experiments.session.resume import replay_session

PROTOCOL = """
name = "cli"
seed = 21
iti_s = 0
[task]
kind = "yes_no"
catch_rate = 0.3
[stimulus]
amplitude_m = "2um"
pitch_m = "2mm"
speed_m_per_s = "40mm/s"
duration_s = "20ms"
ramp_s = "5ms"
[procedure]
method = "staircase"
parameter = "amplitude_m"
[[procedure.tracks]]
start = "3um"
step_sizes = [0.2]
min_level = "0.3um"
max_level = "6um"
max_trials = 6
"""


@pytest.fixture
def session(tmp_path, capsys):
    toml = tmp_path / "p.toml"
    toml.write_text(PROTOCOL)
    code = cli_main(["experiment", "run", str(toml), "--subject", "S01", "--responses", "simulated",
                     "--no-wait", "--quiet", "--out", str(tmp_path / "sessions")])
    out = capsys.readouterr().out
    assert code == 0, out
    path = tmp_path / "sessions" / "sub-S01_ses-01_task-cli.sqlite"
    assert f"session file: {path}" in out and "complete after" in out and "amplitude threshold" in out
    assert re.search(r"^  fitted threshold +[0-9.]+ µm \(95 % interval [0-9.]+ µm to [0-9.]+ µm; psychometric fit\)$",
                     out, re.M), out
    return path


def test_run_status_and_second_session_numbering(session, tmp_path, capsys):
    assert cli_main(["experiment", "status", str(session)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^status +complete: the procedure finished after \d+ trials$", out, re.M), out
    assert re.search(r"^progress +\d+ trials: 6 planned by the procedure and \d+ on top \(catch trials\)$", out, re.M)
    assert "sub-S01 / ses-01 / cli" in out and re.search(r"^display +VirtualBrailleRow, description SHA-256 [0-9a-f]{64}$",
                                                          out, re.M)
    assert "stopped_cleanly" not in out
    # the psychometric fit's threshold with its interval, not the procedure's interpolated crossing
    assert re.search(r"fitted threshold +[0-9.]+ µm \(95 % interval [0-9.]+ µm to [0-9.]+ µm; psychometric fit\)",
                     out), out
    assert re.search(r"^  trials +\d+ trials at \d+ levels from [0-9.]+ µm to [0-9.]+ µm$", out, re.M), out
    assert factory.next_session_path(session.parent, "S01", "cli") == (
        session.parent / "sub-S01_ses-02_task-cli.sqlite", "02")


def test_bids_export_with_sidecar(session, capsys):
    assert cli_main(["experiment", "export", str(session), "--format", "bids"]) == 0
    folder = session.parent / "bids" / "sub-S01" / "ses-01" / "beh"  # default: a BIDS root beside the session
    tsv, sidecar = folder / "sub-S01_ses-01_task-cli_beh.tsv", folder / "sub-S01_ses-01_task-cli_beh.json"
    assert f"wrote {tsv}" in capsys.readouterr().out
    table = pd.read_csv(tsv, sep="\t", keep_default_na=False)
    meta = json.loads(sidecar.read_text())
    assert set(table.columns) <= set(meta) and meta["rt_s"]["Units"] == "s"
    assert meta["TaskName"] == "cli" and meta["Seed"] == 21 and meta["SoftwareName"] == "tactilab"
    trials = SessionLog(session).trials()
    assert list(table["trial_index"]) == [t.trial_index for t in trials]
    assert list(table["rt_s"].astype(float)) == pytest.approx([t.rt_s for t in trials])
    assert all(str(v) in ("True", "False", "n/a") for v in table["correct"])


def test_csv_parquet_and_dataframe_round_trip(session, tmp_path):
    trials = SessionLog(session).trials()
    (csv,) = export_session(session, tmp_path / "out", "csv")
    assert read_trials_csv(csv) == trials
    # pyarrow is in the test extra (pyproject): the Parquet round trip is required, not skipped
    (parquet,) = export_session(session, tmp_path / "out", "parquet")
    from tactilab.data_schemas.experiment_records import trials_from_dataframe

    assert trials_from_dataframe(pd.read_parquet(parquet)) == trials
    assert len(session_dataframe(session)) == len(trials)


def test_json_export_is_the_whole_session(session, tmp_path):
    from tactilab.data_schemas.experiment_records import Session

    (path,) = export_session(session, tmp_path / "out", "json")
    record = Session.model_validate_json(path.read_text())
    assert record.status == "complete" and record.trials == SessionLog(session).trials()
    assert record.protocol.name == "cli" and len(record.session_id) == 32


def test_parquet_without_pyarrow_names_the_missing_dependency(session, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # makes `import pyarrow` fail
    with pytest.raises(ValueError, match="format: 'parquet' needs the optional dependency pyarrow"):
        export_session(session, tmp_path, "parquet")
    assert cli_main(["experiment", "export", str(session), "--format", "parquet"]) == 2
    assert "pip install pyarrow" in capsys.readouterr().err
    assert cli_main(["experiment", "resume", str(session), "--export", "parquet"]) == 2  # before any trial
    assert "--export: 'parquet' needs the optional dependency pyarrow" in capsys.readouterr().err
    with pytest.raises(ValueError, match="format: must be one of"):
        export_session(session, tmp_path, "xlsx")


def test_user_mistakes_give_one_line_and_exit_2(session, tmp_path, capsys):
    toml = tmp_path / "p.toml"
    cases = [
        (["run", str(toml), "--subject", "Jane Doe"], "--subject: must be 1-32 letters or digits"),
        (["run", str(toml), "--subject", "S01", "--session", "1 2"], "--session: must be 1-32 letters"),
        (["run", str(toml), "--subject", "S02", "--device", "hologram"], "--device: must be one of"),
        (["run", str(toml), "--subject", "S02", "--display", "tcp://x:1"], "--display: device 'tcp' is not registered"),
        (["run", str(toml), "--subject", "S02", "--responses", "telepathy"], "--responses: must be 'terminal'"),
        (["run", str(toml), "--subject", "S02", "--responses", "terminal"], "standard input is not a terminal"),
        (["run", str(tmp_path / "missing.toml"), "--subject", "S02"], "protocol file not found"),
        (["run", str(toml), "--subject", "S02", "--out", str(toml / "x")], "--out: cannot create the output folder"),
        (["run", str(toml), "--subject", "S02", "--responses", "simulated", "--observer-threshold", "-1"],
         "--observer-threshold: must be a strain > 0"),
        (["run", str(toml), "--subject", "S02", "--responses", "simulated", "--observer-strain", "skin"],
         "--observer-strain: must be 'surface' or 'display'"),
        (["run", str(toml), "--subject", "S02", "--display", "udp://h", "--responses", "simulated"],
         "--display: expected udp://HOST:PORT"),
        (["export", str(session), "--format", "xml"], "--format: must be one of"),
        (["run", str(toml), "--subject", "S02", "--export", "xlsx"], "--export: must be one of bids, csv, parquet, json"),
        (["resume", str(session), "--export", "xlsx"], "--export: must be one of"),
        (["run", str(toml), "--subject", "S02", "--responses", "simulated", "--observer-threshold", "2mm"],
         "--observer-threshold: unit 'mm' measures length"),
        (["run", str(toml), "--subject", "S01", "--session", "01", "--out", str(session.parent),
          "--responses", "simulated", "--no-wait"], "already exists; resume it"),
        (["resume", str(session), "--device", "stress2"], "--device: "),
        (["resume", str(session), "--device", "stress2"], "display_id: recorded 'VirtualBrailleRow', given 'STReSS2'"),
        (["resume", str(session), "--no-wait"], "is complete; nothing to resume"),
        (["status", str(tmp_path / "nope.sqlite")], "no session file"),
        (["export", str(session), "--out", str(session / "x")], "--out: cannot create the output folder"),
    ]
    for args, message in cases:
        assert cli_main(["experiment", *args]) == 2, args
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1 and "Traceback" not in err, (args, err)


def test_resume_and_status_of_an_interrupted_session(session, tmp_path, capsys):
    """Cut the log back to 3 completed trials plus a planned 4th; resume repeats nothing felt."""
    connection = sqlite3.connect(session)
    last = connection.execute("SELECT min(id) FROM events WHERE kind = 'stimulus_presented' AND trial_index = 3"
                              ).fetchone()[0]
    connection.execute("DELETE FROM events WHERE id >= ?", (last,))
    connection.execute("DELETE FROM trials WHERE trial_index >= 3")
    connection.commit()
    connection.close()
    assert cli_main(["experiment", "status", str(session)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^status +interrupted: killed or crashed \(no stop was recorded\); resume to go on$", out, re.M)
    assert re.search(r"^progress +3 of 6 planned trials \(50 %\)$", out, re.M), out
    assert f"resume with: tactilab experiment resume {session}" in out
    assert cli_main(["experiment", "resume", str(session), "--no-wait", "--quiet", "--json"]) == 0
    captured = capsys.readouterr()
    assert "3 trials done, repeating interrupted trial 3" in captured.err and "complete after" in captured.err
    summary = json.loads(captured.out)  # --json: one object on stdout, messages on stderr
    assert summary["command"] == "experiment resume" and summary["status"] == "complete"
    assert summary["repeated_trials"] == [{"trial_index": 3, "attempts": 2, "felt_before": False,
                                           "why": "the run was killed during it (no stop was recorded)"}]
    trial3 = SessionLog(session).trials()[3]
    assert trial3.attempt == 1 and not trial3.repeated  # planned, never presented: not felt


def test_resume_uses_the_recorded_observer(tmp_path, capsys):
    """A session started with --observer-threshold resumes with the same observer (same answers)."""
    toml = tmp_path / "p.toml"
    toml.write_text(PROTOCOL)
    args = ["--subject", "S05", "--responses", "simulated", "--no-wait", "--quiet", "--observer-threshold", "5e-4"]
    assert cli_main(["experiment", "run", str(toml), *args, "--out", str(tmp_path / "a")]) == 0
    full = tmp_path / "a" / "sub-S05_ses-01_task-cli.sqlite"
    assert SessionLog(full).meta()["responses_config"]["threshold_strain"] == 5e-4
    assert cli_main(["experiment", "run", str(toml), *args, "--out", str(tmp_path / "b")]) == 0
    cut = tmp_path / "b" / "sub-S05_ses-01_task-cli.sqlite"
    connection = sqlite3.connect(cut)
    connection.execute("DELETE FROM events WHERE trial_index >= 2 OR kind = 'session_complete'")
    connection.execute("DELETE FROM trials WHERE trial_index >= 2")
    connection.commit()
    connection.close()
    assert cli_main(["experiment", "resume", str(cut), "--no-wait", "--quiet"]) == 0
    capsys.readouterr()
    assert [(t.level, t.response) for t in SessionLog(cut).trials()] == \
        [(t.level, t.response) for t in SessionLog(full).trials()]
    connection = sqlite3.connect(cut)  # cut again, then try to resume with another observer
    connection.execute("DELETE FROM events WHERE trial_index >= 2 OR kind = 'session_complete'")
    connection.execute("DELETE FROM trials WHERE trial_index >= 2")
    connection.commit()
    connection.close()
    assert cli_main(["experiment", "resume", str(cut), "--no-wait", "--observer-threshold", "1e-3"]) == 2
    assert "responses: the session was recorded with simulated responses configured as" in capsys.readouterr().err


def test_damaged_logs_are_refused(session):
    connection = sqlite3.connect(session)
    connection.execute("DELETE FROM trials WHERE trial_index = 1")
    connection.commit()
    connection.close()
    with pytest.raises(ValueError, match="completed trials are not contiguous \\(trial 1 missing"):
        replay_session(session)


def test_observer_feeling_the_display_is_recorded_and_resumed(tmp_path, capsys):
    toml = tmp_path / "p.toml"
    toml.write_text(PROTOCOL)
    args = ["--subject", "S06", "--responses", "simulated", "--no-wait", "--quiet", "--observer-strain", "display"]
    assert cli_main(["experiment", "run", str(toml), *args, "--out", str(tmp_path)]) == 0
    session = tmp_path / "sub-S06_ses-01_task-cli.sqlite"
    assert SessionLog(session).meta()["responses_config"]["strain"] == "display"
    connection = sqlite3.connect(session)
    connection.execute("DELETE FROM events WHERE trial_index >= 3 OR kind = 'session_complete'")
    connection.execute("DELETE FROM trials WHERE trial_index >= 3")
    connection.commit()
    connection.close()
    assert cli_main(["experiment", "resume", str(session), "--no-wait", "--quiet", "--observer-strain", "surface"]) == 2
    assert "responses: the session was recorded with simulated responses" in capsys.readouterr().err
    assert cli_main(["experiment", "resume", str(session), "--no-wait", "--quiet"]) == 0


def test_make_responses_options():
    from tactilab.data_schemas.experiment import Protocol

    protocol = Protocol.from_toml(Path(__file__).resolve().parents[1] / "examples" / "protocol_psi.toml")
    udp_like = object()
    with pytest.raises(ValueError, match="strain: 'display' needs a SimulatedDisplay"):
        factory.make_responses("simulated", protocol, udp_like, strain="display")
    with pytest.raises(ValueError, match="strain: must be 'surface' or 'display', got 'skin'"):
        factory.make_responses("simulated", protocol, udp_like, strain="skin")
    with pytest.raises(ValueError, match="custom strain function: resume it from Python"):
        factory.make_responses("simulated", protocol, udp_like, recorded={"strain": "custom"})
    observer = factory.make_responses("simulated", protocol, udp_like, threshold="1e-3",
                                      recorded={"strain": "surface", "exponent": 2.0})
    assert observer.config["threshold_strain"] == 1e-3 and observer.config["exponent"] == 2.0


def test_factory_specs(tmp_path):
    assert devices.description_from_spec("stress2").display_id == "STReSS2"
    path = DisplayDescription.braille_row().save(tmp_path / "d.json")
    assert devices.description_from_spec(str(path)) == DisplayDescription.braille_row()
    for n in range(1, 1000):
        (tmp_path / f"sub-S9_ses-{n:02d}_task-t.sqlite").touch()
    with pytest.raises(ValueError, match="folder: .* already holds 999 sessions"):
        factory.next_session_path(tmp_path, "S9", "t")


def test_recorder_open_failures_are_recording_errors(tmp_path, monkeypatch):
    (tmp_path / "m.sqlite").touch()
    lock = _FileLock(tmp_path / "m.sqlite")
    with pytest.raises(RecordingError, match="cannot use WAL journaling"):
        Recorder._connect(Path(":memory:"), lock)

    def broken(*args, **kwargs):
        raise sqlite3.OperationalError("disk I/O error")

    monkeypatch.setattr(sqlite3, "connect", broken)
    with pytest.raises(RecordingError, match="cannot create .*disk I/O error"):
        Recorder.create(tmp_path / "a.sqlite", {})
    (tmp_path / "b.sqlite").touch()
    with pytest.raises(RecordingError, match="cannot open .* for writing \\(disk I/O error\\)"):
        Recorder.open(tmp_path / "b.sqlite")


def test_factory_rejects_bad_specs(tmp_path):
    """The CLI-edge builders raise ValueError naming the option (also checked through the CLI above)."""
    from tactilab.data_schemas.experiment import Protocol

    protocol_file = tmp_path / "p.toml"
    protocol_file.write_text(PROTOCOL)
    protocol = Protocol.from_toml(protocol_file)
    description = DisplayDescription.braille_row()
    with pytest.raises(ValueError, match=r"spec: must be one of \['braille-row', 'stress2'\] .*got 'x.json'"):
        devices.description_from_spec("x.json")  # no such file
    with pytest.raises(ValueError, match=r"spec: device 'tcp' is not registered \(known: \[.*'simulated', 'udp'.*\]\)"):
        devices.open_display("tcp://h:1", description)
    with pytest.raises(ValueError, match="spec: must be 'terminal' or 'simulated', got 'mind'"):
        factory.responses_from_spec("mind", protocol)
    display = devices.open_display("simulated", description, realtime=False)
    try:
        with pytest.raises(ValueError, match="threshold: must be a strain > 0, got '0'"):
            factory.make_responses("simulated", protocol, display, threshold="0")
    finally:
        display.close()


def test_a_resume_with_a_laxer_display_description_is_refused(tmp_path, capsys):
    """Same display_id, 100 000 times the traction limit: refused, naming the field."""
    toml = tmp_path / "p.toml"
    toml.write_text(PROTOCOL)
    argv = ["experiment", "run", str(toml), "--subject", "S01", "--responses", "simulated", "--no-wait", "--quiet",
            "--out", str(tmp_path)]
    path = tmp_path / "sub-S01_ses-01_task-cli.sqlite"
    nominal = DisplayDescription.braille_row()
    lax = tmp_path / "lax.json"
    lax.write_text(nominal.model_copy(update={"max_traction_pa": nominal.max_traction_pa * 1e5}).model_dump_json())
    # a session interrupted after its creation: cut it short by deleting its completion
    assert cli_main(argv) == 0
    with contextlib.closing(sqlite3.connect(path)) as db, db:
        db.execute("DELETE FROM events WHERE kind = 'session_complete'")
        db.execute("DELETE FROM trials WHERE trial_index >= 3")
        db.execute("DELETE FROM events WHERE trial_index >= 3")
    capsys.readouterr()
    assert cli_main(["experiment", "resume", str(path), "--device", str(lax), "--no-wait", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--device: " in err and "max_traction_pa: recorded 50000.0, given 5000000000.0" in err
    from tactilab.experiments import SimulatedDisplay, SimulatedObserver, resume_session

    protocol = replay_session(path).protocol
    with pytest.raises(ValueError, match=r"display: .* \(max_traction_pa: recorded 50000.0, given 5000000000.0\)"):
        resume_session(path, SimulatedDisplay(DisplayDescription.load(lax), realtime=False),
                       SimulatedObserver(protocol), realtime=False)
    # by default the resume uses the recorded description, and the export carries it with its hash
    assert cli_main(["experiment", "resume", str(path), "--no-wait", "--quiet"]) == 0
    meta = SessionLog(path).meta()
    from tactilab.experiments.devices import description_record

    # the whole description, less the link fields that hold their defaults (pairing key file, lookahead)
    assert meta["display_description"] == description_record(nominal)[0] and len(meta["display_sha256"]) == 64
    assert set(nominal.model_dump(mode="json")) - set(meta["display_description"]) == {"pairing_key_file",
                                                                                      "lookahead_s"}
    export_session(path, tmp_path / "bids")
    sidecar = json.loads(next((tmp_path / "bids").rglob("*_beh.json")).read_text())
    assert sidecar["DisplayDescription"]["max_traction_pa"] == 50000.0
    assert sidecar["DisplayDescriptionSHA256"] == meta["display_sha256"]


def test_resume_replays_the_log_once(session, monkeypatch, capsys):
    with contextlib.closing(sqlite3.connect(session)) as db, db:
        db.execute("DELETE FROM events WHERE kind = 'session_complete' OR trial_index >= 3")
        db.execute("DELETE FROM trials WHERE trial_index >= 3")
    from tactilab.experiments.session import resume

    calls = []
    original = resume.replay_log
    monkeypatch.setattr(resume, "replay_log", lambda log: (calls.append(1), original(log))[1])
    assert cli_main(["experiment", "resume", str(session), "--no-wait", "--quiet"]) == 0
    # one replay to resume, one more (read only) for the end-of-run summary's status
    assert len(calls) == 2 and "3 trials done" in capsys.readouterr().out
