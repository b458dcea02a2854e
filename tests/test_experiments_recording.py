"""The recorder and runner: event order, durability settings, full disk, read-only file, locks."""

from __future__ import annotations

import contextlib
import re
import json
import os
import signal
import sqlite3

import numpy as np
import pytest

from tactilab.cli.main import main as cli_main
from tactilab.data_schemas.display import DisplayDescription
from tactilab.data_schemas.experiment import Protocol
from tactilab.experiments.devices.display import Display, PlaybackReport
from tactilab.experiments.procedures.build import make_procedure
from tactilab.experiments.session.recording import Recorder, RecordingError, SessionLockedError, SessionLog
from tactilab.experiments.session.responses import SimulatedObserver
from tactilab.experiments.session.resume import replay_session, resume_session, session_status
from tactilab.experiments.session.runner import Runner, new_session

PROTOCOL = {
    "name": "rec", "seed": 11, "iti_s": 0, "task": {"kind": "2ifc"},
    "stimulus": {"amplitude_m": "2um", "pitch_m": "2mm", "speed_m_per_s": "40mm/s", "duration_s": "20ms",
                 "ramp_s": "5ms"},
    "procedure": {"method": "staircase", "parameter": "amplitude_m", "tracks": [
        {"start": "3um", "step_sizes": [0.2, 0.1], "min_level": "0.3um", "max_level": "6um", "max_trials": 8}]},
}


class CheckingDisplay(Display):
    """A fake display that, each time it is driven, reads the session with its own connection
    and records which event of the current trial was committed last."""

    def __init__(self, path, hook=None):
        super().__init__(DisplayDescription.braille_row())
        self.path, self.hook = path, hook
        self.plays, self.zeros, self.last_kinds = 0, 0, []

    def _play(self, frames, frame_rate_hz):
        self.plays += 1
        with contextlib.closing(sqlite3.connect(f"file:{self.path}?mode=ro", uri=True)) as reader:
            kind, index = reader.execute(
                "SELECT kind, trial_index FROM events WHERE kind != 'safety_intervention' "
                "ORDER BY id DESC LIMIT 1").fetchone()
        self.last_kinds.append((kind, index))
        if self.hook is not None:
            self.hook(self)
        return PlaybackReport(frames_sent=len(frames), late=0, missing=0, acked=len(frames))

    def _zero(self):
        self.zeros += 1


def _runner(tmp_path, display_hook=None, protocol=None):
    protocol = protocol or Protocol.model_validate(PROTOCOL)
    path = tmp_path / "s.sqlite"
    recorder = Recorder.create(path, {"subject": "S01", "session": "01", "protocol": protocol.model_dump(mode="json"),
                                      "seed": protocol.seed, "package_version": "test", "display_id": "VirtualBrailleRow",
                                      "responses": "simulated"})
    display = CheckingDisplay(path, display_hook)
    runner = Runner(protocol, recorder, display, SimulatedObserver(protocol), subject="S01", session="01",
                    procedure=make_procedure(protocol.procedure, protocol.task.guess_rate), realtime=False)
    return runner, recorder, display, path


def test_stimulus_presented_is_committed_before_the_display_is_driven(tmp_path):
    runner, recorder, display, path = _runner(tmp_path)
    result = runner.run()
    recorder.close()
    assert result.status == "complete" and display.plays == 16  # 8 trials x 2 intervals
    assert display.last_kinds == [("stimulus_presented", i // 2) for i in range(16)]
    kinds = [e["kind"] for e in SessionLog(path).events() if e["kind"] != "safety_intervention"]
    assert kinds == ["trial_planned", "stimulus_presented", "response", "trial_complete"] * 8 + ["session_complete"]


def test_session_uses_wal_and_synchronous_full(tmp_path):
    runner, recorder, _, _ = _runner(tmp_path)
    assert recorder.connection.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert recorder.connection.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
    recorder.close()


@pytest.mark.parametrize("failure", ["full_disk", "read_only"])
def test_write_failure_stops_before_the_next_stimulus_and_keeps_the_data(tmp_path, failure):
    """Disk full (``PRAGMA max_page_count`` pinned to the current size) or a read-only database
    (``PRAGMA query_only``), from trial 2 on: the run stops with a clear message, the display is
    zeroed, no stimulus is driven without its committed ``stimulus_presented`` event, every
    committed trial is intact, and the session resumes to the same end as an uninterrupted run."""

    def hook(display):
        if display.plays == 5:  # trial 2, first interval: from now on writes fail
            connection = runner.recorder.connection
            if failure == "full_disk":
                pages = connection.execute("PRAGMA page_count").fetchone()[0]
                connection.execute(f"PRAGMA max_page_count = {pages}")
            else:
                connection.execute("PRAGMA query_only = ON")

    runner, recorder, display, path = _runner(tmp_path, hook)
    message = "database or disk is full" if failure == "full_disk" else "readonly database"
    with pytest.raises(RecordingError, match=f"{message}.*stopped before the next stimulus; \\d+ completed trials"):
        runner.run()
    recorder.close()
    log = SessionLog(path)
    completed = [t.trial_index for t in log.trials()]
    presented = {e["trial_index"] for e in log.events("stimulus_presented")}
    assert completed == list(range(len(completed))) and len(completed) >= 2
    assert display.plays == 2 * len(presented) and display.zeros >= 1
    assert all(kind == "stimulus_presented" for kind, _ in display.last_kinds)
    assert log.connection.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    if failure == "read_only":
        assert completed == [0, 1] and display.plays == 6
    protocol = Protocol.model_validate(PROTOCOL)
    resumed = resume_session(path, CheckingDisplay(path), SimulatedObserver(protocol), realtime=False)
    reference = new_session(protocol, tmp_path / "ref.sqlite", CheckingDisplay(tmp_path / "ref.sqlite"),
                            SimulatedObserver(protocol), subject="S01", realtime=False)
    assert resumed.status == "complete" and resumed.estimate == reference.estimate
    trials = SessionLog(path).trials()
    interrupted = len(completed)
    assert [t.repeated for t in trials] == [i == interrupted and interrupted in presented for i in range(len(trials))]


def test_a_second_runner_on_a_locked_session_is_refused(tmp_path, capsys):
    runner, recorder, _, path = _runner(tmp_path)
    protocol = Protocol.model_validate(PROTOCOL)
    with pytest.raises(SessionLockedError, match="is locked by a running runner.*pid"):
        resume_session(path, CheckingDisplay(path), SimulatedObserver(protocol), realtime=False)
    assert session_status(path)["status"] == "running"
    assert cli_main(["experiment", "resume", str(path), "--no-wait", "--quiet"]) == 2
    assert "locked by a running runner" in capsys.readouterr().err
    recorder.close()
    assert session_status(path)["status"] == "interrupted"  # no trial yet, lock released


def test_existing_session_file_is_not_overwritten(tmp_path):
    path = tmp_path / "s.sqlite"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="already exists; resume it"):
        Recorder.create(path, {})
    assert path.read_bytes() == b"precious"


def test_unknown_event_kind_and_missing_files_are_refused(tmp_path):
    runner, recorder, _, path = _runner(tmp_path)
    with pytest.raises(ValueError, match="kind: must be one of"):
        recorder.log("coffee_break")
    recorder.close()
    with pytest.raises(FileNotFoundError, match="no session file"):
        SessionLog(tmp_path / "nope.sqlite")
    with pytest.raises(FileNotFoundError, match="no session file"):
        Recorder.open(tmp_path / "nope.sqlite")
    (tmp_path / "junk.sqlite").write_bytes(b"not a database at all" * 10)
    with pytest.raises(ValueError, match="not a tactilab session database"):
        SessionLog(tmp_path / "junk.sqlite")


def test_a_log_that_does_not_match_its_protocol_is_refused(tmp_path):
    """Replay re-derives every level; a tampered level is caught, naming the trial."""
    runner, recorder, _, path = _runner(tmp_path)
    runner.run()
    record = json.loads(recorder.connection.execute("SELECT record FROM trials WHERE trial_index = 2").fetchone()[0])
    record["level"] = 5.5e-6
    recorder.connection.execute("UPDATE trials SET record = ? WHERE trial_index = 2", (json.dumps(record),))
    recorder.close()
    with pytest.raises(ValueError, match="history: trial 2 recorded level 5.5e-06.*does not match this protocol"):
        replay_session(path)


def test_completed_session_cannot_be_resumed(tmp_path):
    runner, recorder, _, path = _runner(tmp_path)
    runner.run()
    recorder.close()
    protocol = Protocol.model_validate(PROTOCOL)
    with pytest.raises(ValueError, match="is complete; nothing to resume"):
        resume_session(path, CheckingDisplay(path), SimulatedObserver(protocol), realtime=False)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT, signal.SIGUSR1])
def test_a_stop_signal_during_a_stimulus_zeroes_and_stops_cleanly(tmp_path, signum):
    """SIGTERM, SIGHUP, SIGQUIT or SIGUSR1 mid-stimulus: the safety layer zeroes the display, the
    runner logs the stop and returns 'interrupted' with the lock released; resuming repeats the
    interrupted trial."""

    def hook(display):
        if display.plays == 3:
            os.kill(os.getpid(), signum)

    previous = signal.getsignal(signum)
    runner, recorder, display, path = _runner(tmp_path, hook)
    result = runner.run()
    recorder.close()
    assert signal.getsignal(signum) == previous
    assert result.status == "interrupted" and result.n_completed == 1 and display.zeros >= 1
    events = SessionLog(path).events()
    assert events[-1]["kind"] == "session_stopped"
    assert signal.Signals(signum).name in events[-1]["payload"]["reason"]
    kind = "zero_on_" + signal.Signals(signum).name.lower()
    assert any(e["kind"] == "safety_intervention" and e["payload"]["kind"] == kind for e in events)
    status = session_status(path)
    assert status["status"] == "interrupted" and status["interrupted_trial"] == 1 and status["stopped_cleanly"]


def test_replay_rebuilds_the_exact_procedure_state(tmp_path):
    """State after replaying the log equals the live state at the end of the run, bit for bit."""
    protocol = Protocol.model_validate({**PROTOCOL, "procedure": {
        "method": "psi", "parameter": "amplitude_m", "levels": {"start": "0.3um", "stop": "6um", "n": 9, "scale": "log"},
        "parameters": {"threshold": {"start": "0.5um", "stop": "5um", "n": 8, "scale": "log"},
                       "slope": [2.0, 4.0], "lapse": [0.0, 0.05]}, "n_trials": 6}})
    runner, recorder, _, path = _runner(tmp_path, protocol=protocol)
    runner.run()
    recorder.close()
    live = runner.procedure.state()
    replayed = replay_session(path).procedure.state()
    np.testing.assert_array_equal(replayed["log_posterior"], live["log_posterior"])


def test_an_unexpected_display_error_zeroes_logs_and_is_reported_as_failed(tmp_path):
    def hook(display):
        if display.plays == 3:
            raise RuntimeError("amplifier fault")

    runner, recorder, display, path = _runner(tmp_path, hook)
    with pytest.raises(RuntimeError, match="amplifier fault"):
        runner.run()
    recorder.close()
    assert display.zeros >= 1
    status = session_status(path)
    assert status["status"] == "failed" and status["completed"] == 1 and not status["stopped_cleanly"]
    protocol = Protocol.model_validate(PROTOCOL)
    assert resume_session(path, CheckingDisplay(path), SimulatedObserver(protocol), realtime=False).status == "complete"
    assert session_status(path)["status"] == "complete"


# ----- one owner per session ------------------------------------------------------------------
def test_the_lock_is_on_the_database_itself_so_deleting_files_never_admits_a_second_runner(tmp_path):
    runner, recorder, _, path = _runner(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("s.sqlite-")) == ["s.sqlite"]
    for stray in (path.with_name(path.name + ".lock"), path.with_name(path.name + ".partial")):
        stray.unlink(missing_ok=True)  # what an audit did to the old separate lock file
    with pytest.raises(SessionLockedError, match=r"is locked by a running runner \(pid \d+ on .* heartbeat"):
        Recorder.open(path)
    recorder.close()
    Recorder.open(path).close()


def test_a_runner_that_lost_ownership_stops_before_the_next_stimulus(tmp_path):
    """Another process became the owner (it bypassed the lock): the next commit finds a foreign
    token, and the runner zeroes the display and stops; nothing more is written or played."""

    def take_over(display):
        if display.plays == 3:
            with contextlib.closing(sqlite3.connect(display.path)) as other, other:
                other.execute("UPDATE owner SET token = 'intruder', pid = 4242")

    runner, recorder, display, path = _runner(tmp_path, take_over)
    with pytest.raises(RecordingError, match="now owned by another runner \\(pid 4242 on .*stopped writing"):
        runner.run()
    recorder.close()
    assert display.plays == 4 and display.zeros >= 1  # the trial's two intervals, then nothing
    log = SessionLog(path)
    try:
        assert len(log.trials()) == 1 and log.owner()["pid"] == 4242
    finally:
        log.close()


def test_a_closed_session_is_one_self_contained_file(tmp_path):
    """No -wal, -shm, .lock or .partial is left; the file stays in WAL mode (header bytes 18-19 =
    2: no journal-mode switch on open or close) and is readable from read-only media as immutable."""
    runner, recorder, _, path = _runner(tmp_path)
    runner.run()
    assert recorder.close() is True
    assert [p.name for p in tmp_path.iterdir()] == ["s.sqlite"]
    assert path.read_bytes()[18:20] == b"\x02\x02"
    with contextlib.closing(sqlite3.connect(f"file:{path}?immutable=1", uri=True)) as frozen:  # read-only medium
        assert frozen.execute("SELECT count(*) FROM trials").fetchone()[0] == 8
    status = session_status(path)
    assert status["status"] == "complete" and status["completed"] == 8
    assert status["owner"]["pid"] == os.getpid()
    assert [p.name for p in tmp_path.iterdir()] == ["s.sqlite"], "reading leaves nothing behind"


def test_a_trial_costs_two_commits(tmp_path, monkeypatch):
    """Plan with presentation, response with completion: two fsynced transactions per trial."""
    runner, recorder, _, path = _runner(tmp_path)
    commits = []
    original = Recorder._write
    monkeypatch.setattr(Recorder, "_write", lambda self, statements: (commits.append(
        [sql.split()[0] + (" " + params[0] if sql.startswith("INSERT INTO events") else "")
         for sql, params in statements]), original(self, statements))[1])
    runner.run()
    recorder.close()
    trial_commits = [c for c in commits if any("trial_planned" in x or "trial_complete" in x for x in c)]
    assert len(trial_commits) == 2 * 8
    assert trial_commits[0] == ["INSERT trial_planned", "INSERT stimulus_presented"]
    assert trial_commits[1] == ["INSERT response", "INSERT trial_complete", "INSERT"]
    assert len(commits) == 2 * 8 + 1  # and session_complete


def test_torn_foreign_and_incomplete_session_files_give_one_line(tmp_path, capsys):
    runner, recorder, _, path = _runner(tmp_path)
    runner.run()
    recorder.close()
    torn = tmp_path / "torn.sqlite"
    torn.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])
    foreign = tmp_path / "foreign.sqlite"
    with contextlib.closing(sqlite3.connect(foreign)) as db, db:
        db.execute("CREATE TABLE events (x)")
    incomplete = tmp_path / "incomplete.sqlite"
    incomplete.write_bytes(path.read_bytes())
    with contextlib.closing(sqlite3.connect(incomplete)) as db, db:
        db.execute("DELETE FROM meta WHERE key = 'seed'")
    for bad, message in ((torn, "(is damaged or )?not a tactilab session"), (foreign, "(is damaged or )?not a tactilab"),
                         (incomplete, "lacks the metadata \\['seed'\\]")):
        for action in ("status", "export"):
            assert cli_main(["experiment", action, str(bad), "--format", "json"][:3 if action == "status" else 5]) == 2
            err = capsys.readouterr().err
            assert len(err.strip().splitlines()) == 1 and str(bad) in err, err
            assert re.search(message, err), err
